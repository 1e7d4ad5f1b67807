#!/bin/bash
# A crack survey of 10,000 views in 4 parts as a Slurm job array, then
# joined into exactly what one run prints. Submit with
#   sbatch docs/slurm-cracks.sh
# and, when the array is done,
#   terraclip merge cracks-part-{0,1,2,3}.json > cracks.json
#SBATCH --job-name=terraclip-cracks
#SBATCH --array=0-3
#SBATCH --cpus-per-task=4
#SBATCH --mem=4G
#SBATCH --output=cracks-part-%a.log
set -euo pipefail
N=4
terraclip cracks --views 10000 --lod all --json \
  --shard "${SLURM_ARRAY_TASK_ID}/${N}" > "cracks-part-${SLURM_ARRAY_TASK_ID}.json"
