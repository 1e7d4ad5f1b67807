#!/usr/bin/env bash
# Fetches ETOPO5 (NOAA NGDC, 5 arc-minute global relief, public domain) from
# Debian's ferret-datasets package and writes it as the 16-bit PNG and JSON
# sidecar the docs use: etopo5_16.png (4320 x 2161, north up, column 0 at
# 180 W) and etopo5.json (metres = -10376 + code x 18209/65535, cell
# 9266.257 m). Needs apt-get (no root: it only downloads), dpkg-deb and
# python3, as on a fresh Debian 12.
#
#   docs/get-etopo5.sh [DIR]     # default: the current folder
set -euo pipefail
out=$(realpath "${1:-.}")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
apt-get download ferret-datasets=7.6.0-5 >/dev/null 2>&1 || apt-get download ferret-datasets >/dev/null
dpkg-deb -x ferret-datasets_*.deb x
cdf=x/usr/share/ferret-vis/data/etopo5.cdf
echo "1455d5e5feebd183d0bef5538a750ca8a44801e1503f964df900831c224459ce  $cdf" | sha256sum -c --quiet
python3 - "$cdf" "$out" <<'PY'
# netCDF-3 classic, read with the standard library alone: the header's
# dimensions and variables, then ROSE (float32, lat x lon, south first,
# column 0 at 0 E), flipped north up and rolled so column 0 is 180 W.
import json, struct, sys, zlib
data = open(sys.argv[1], "rb").read()
assert data[:3] == b"CDF" and data[3] in (1, 2), "not netCDF-3"
off8 = data[3] == 2
at = 8
def u32():
    global at
    v = struct.unpack_from(">I", data, at)[0]; at += 4; return v
def name():
    global at
    n = u32(); s = data[at:at + n].decode(); at += (n + 3) // 4 * 4; return s
SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 4, 6: 8}
def atts():
    global at
    tag, n = u32(), u32()
    for _ in range(n):
        name(); t = u32(); k = u32(); at += (k * SIZE[t] + 3) // 4 * 4
def dims():
    tag, n = u32(), u32()
    return [(name(), u32()) for _ in range(n)]
d = dims(); atts()
tag, nv = u32(), u32()
vars = {}
for _ in range(nv):
    vn = name(); ids = [u32() for _ in range(u32())]; atts()
    t = u32(); u32()
    begin = struct.unpack_from(">Q" if off8 else ">I", data, at)[0]; at += 8 if off8 else 4
    vars[vn] = ([d[i][1] for i in ids], t, begin)
shape, t, begin = vars["ROSE"]
assert t == 5 and shape == [2161, 4320], (shape, t)
h, w = shape
rows = [struct.unpack_from(">%df" % w, data, begin + 4 * w * r) for r in range(h)]
rows.reverse()
lo, scale = -10376.0, 18209.0 / 65535.0
raw = bytearray()
for r in rows:
    r = r[w // 2:] + r[:w // 2]
    raw.append(0)
    raw += struct.pack(">%dH" % w, *(min(65535, max(0, round((v - lo) / scale))) for v in r))
def chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)) \
    + chunk(b"IDAT", zlib.compress(bytes(raw), 9)) + chunk(b"IEND", b"")
out = sys.argv[2]
open(out + "/etopo5_16.png.tmp", "wb").write(png)
side = {
    "name": "etopo5", "width": w, "height": h, "min": -10376.0, "max": 7833.0, "units": "metres",
    "cell_size_m": {"x": 9266.257, "y": 9266.257},
    "png16": {"file": "etopo5_16.png", "png16_offset_m": lo, "png16_scale_m_per_unit": scale,
              "decode": "elev_m = png16_offset_m + value * png16_scale_m_per_unit"},
    "source": {"registry": "Debian (bookworm)", "package": "ferret-datasets", "version": "7.6.0-5",
               "path": "/usr/share/ferret-vis/data/etopo5.cdf", "variable": "ROSE (float32, netCDF-3)",
               "license": "NOAA NGDC ETOPO5 (1988), US Government public domain"},
    "nodata": None,
}
open(out + "/etopo5.json.tmp", "w").write(json.dumps(side, indent=2) + "\n")
import os
os.replace(out + "/etopo5_16.png.tmp", out + "/etopo5_16.png")
os.replace(out + "/etopo5.json.tmp", out + "/etopo5.json")
print("wrote %s/etopo5_16.png (%d x %d) and etopo5.json" % (out, w, h))
PY
