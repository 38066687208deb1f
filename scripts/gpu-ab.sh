#!/usr/bin/env bash
# A/B timing of mochi builds on the GPU machine, alternating binaries in one call so both see the
# same device state. Carry .bin/ with one release binary per build (.bin/mochi-NAME) and .gl/.
# Usage there: `BINS="base main" ROUNDS=2 bash scripts/gpu-ab.sh [detect] [dem] [targets]`.
# Prints GPU-timestamp medians of 1M-sphere detection (slab and polylog, random layout), DEM steps
# (freefall and polylog, ms per step split build / DCD / update), and the bench targets.
set -euo pipefail
cd "$(dirname "$0")/.."
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
bins=(${BINS:-main})
rounds=${ROUNDS:-2}
parts=("$@")
[ ${#parts[@]} -gt 0 ] || parts=(detect dem targets)
out=${OUT:-/tmp/ab}
mkdir -p "$out"
want() { [[ " ${parts[*]} " == *" $1 "* ]]; }
for round in $(seq "$rounds"); do
    for b in "${bins[@]}"; do
        m=".bin/mochi-$b"
        # The paper's law: named where the build knows the `contact` key (older builds have no
        # other law).
        law=()
        "$m" simulate --scene freefall -n 8 --steps 0 --set contact=linear --overwrite \
            -o "$out/probe-$b" >/dev/null 2>&1 && law=(--set contact=linear)
        if want detect; then
            for scene in slab polylog; do
                echo "== round $round $b detect $scene"
                "$m" detect --scene "$scene" -n 1000000 --layout random --backend wgpu-compute \
                    --repeat 30 -o "$out/pairs-$b-$scene.csv" 2>&1 | grep -oE "GPU time: [^|]*"
            done
        fi
        if want dem; then
            for scene in freefall polylog; do
                echo "== round $round $b dem $scene"
                "$m" simulate --scene "$scene" -n 1000000 --steps 1000 --backend wgpu-compute \
                    --set frame_every=0 "${law[@]}" --overwrite -o "$out/sim-$b-$scene" 2>&1 | grep -A2 "per step" | tail -1
            done
        fi
    done
done
if want targets; then
    for b in "${bins[@]}"; do
        echo "== $b bench targets"
        ".bin/mochi-$b" bench --scale paper --experiments targets --backends wgpu-compute \
            --repeats 3 -q -o "$out/bench-$b" 2>&1 | tail -12
    done
fi
