#!/usr/bin/env bash
# One prepared run for a lent GPU machine (about 15 minutes in all; this
# script keeps under 9). That machine has no Rust toolchain, so the release
# binary is built here and carried:
#
#   cargo build --release && strip -o .gpu/terraclip target/release/terraclip
#   (device run, carry [".gl", ".gpu"]) bash .ci/gpu-window.sh
#   ONLY_COMPARE=1 bash .ci/gpu-window.sh    # the compare step alone
#
# `.gl` holds Debian's Vulkan and GL loader packages (the device README
# says how to fetch them). Every figure is written as JSON under $OUT.
# Nothing here changes the project.
set -u
OUT=${OUT:-./gpu-out}; mkdir -p "$OUT"
log() { echo "[$(date +%T)] $*" | tee -a "$OUT/log.txt"; }
if [ -d .gl ]; then for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig; fi
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json}
export __EGL_VENDOR_LIBRARY_FILENAMES=${__EGL_VENDOR_LIBRARY_FILENAMES:-/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json}
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >"$OUT/gpu.txt" 2>&1 || true
B=${B:-.gpu/terraclip}
S=$(mktemp -d)   # scratch: images and exports that need not come back
run() { local name=$1; shift; log "$name"; timeout "${T:-120}" "$B" "$@" --json >"$S/$name.json" 2>"$S/$name.err"; echo "rc=$?" >>"$S/$name.err"; }
[ "${ONLY_COMPARE:-0}" = 1 ] || {
run check-gpu-vulkan check-gpu --frames 3 --out "$S/cg"
T=200 run check-gpu-vulkan-path check-gpu golden/default.toml golden/grazing-horizon.toml golden/synthesis-close.toml golden/wireframe.toml --frames 100 --out "$S/cgp"
run check-gpu-gl check-gpu --api gl --out "$S/cggl"
run check-gpu-update check-gpu golden/synthesis-close.toml golden/pack-lossy.toml --update gpu --frames 20 --out "$S/cgu"
run bench-default bench
run bench-update bench golden/synthesis-close.toml --update
# Every cost per scheme on the GPU (timestamps): jacksboro is in the
# repository; etopo5 only where target/etopo5_16.png was carried.
T=240 run tradeoff-gpu-jacksboro tradeoff --heightmap tests/data/jacksboro_16.png --effects lambert,morph --gpu --out "$S/tj"
[ -f target/etopo5_16.png ] && T=300 run tradeoff-gpu-etopo5 tradeoff --heightmap target/etopo5_16.png --effects lambert,morph --gpu --out "$S/te"
}
# compare: the GPU's own frame of each golden against its export, tiered
# and FLIP (the render writes colour alone).
for g in golden/*.toml; do
  s=$(basename "$g" .toml)
  "$B" export "$g" --out "$S/exp-$s" >/dev/null 2>>"$S/compare.err" \
    && "$B" render "$g" --backend gpu -o "$S/gpu-$s.png" >/dev/null 2>>"$S/compare.err" || continue
  for m in tiered flip; do
    "$B" compare "$S/exp-$s" --image "$S/gpu-$s.png" --mode $m --json >"$S/compare-$m-$s.json" 2>>"$S/compare.err"
    echo "$s $m rc=$?" >>"$S/compare.err"
  done
done
log "compare done"
# Eight files at most come back: the JSON figures in one tarball, the log,
# and the worst frames' images of the Vulkan sweep.
tar -C "$S" -czf "$OUT/figures.tgz" $(cd "$S" && ls *.json *.err)
ls "$S/cg" 2>/dev/null | head -20 >>"$OUT/log.txt"
log "done"
