#!/usr/bin/env bash
# Issue 43's dense frictional bed, timed: each mochi binary given settles the HCP block of
# make_block.py for 0.1 s (scene.toml's 20,000 steps), then every binary times STEPS more steps
# (default 2000; SETTLE=N settles N steps instead) from its own settled bed and from the first binary's (the same bed for all:
# a later binary reads an earlier one's checkpoint), ROUNDS times (default 2), alternating.
# Prints one line per timed run: binary, bed, contacts at the end, and the summary's ms per
# step (build / DCD / update / total; GPU timestamps where the backend has them).
#
# Usage: benches/hcp_block/run.sh WORK_DIR MOCHI [MOCHI ...]
#   BACKEND=wgpu-compute (default) | optix | wgpu-rq | cpu; PYTHON=python3 (with NumPy)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=${1:?usage: run.sh WORK_DIR MOCHI [MOCHI ...]}
shift
[ $# -ge 1 ] || { echo "usage: run.sh WORK_DIR MOCHI [MOCHI ...]" >&2; exit 2; }
backend=${BACKEND:-wgpu-compute}
steps=${STEPS:-2000}
rounds=${ROUNDS:-2}
mkdir -p "$work"
cp "$here/scene.toml" "$work/scene.toml"
[ -e "$work/block.npy" ] || "${PYTHON:-python3}" "$here/make_block.py" "$work/block.npy"

settled=${SETTLE:-$(sed -n 's/^steps = //p' "$here/scene.toml")}
label() { basename "$1"; }
for bin in "$@"; do
    echo "settling with $(label "$bin") ($backend)"
    "$bin" simulate "$work/scene.toml" --backend "$backend" -q --overwrite --steps "$settled" \
        -o "$work/settled-$(label "$bin")" 2>&1 | grep -E '^\| [a-z]|^scene'

done
first=$(label "$1")
echo "| round | binary | bed | contacts | build / DCD / update / total [ms] |"
echo "| --- | --- | --- | --- | --- |"
for round in $(seq 1 "$rounds"); do
    for bin in "$@"; do
        own=$(label "$bin")
        beds=("$own")
        [ "$own" = "$first" ] || beds+=("$first")
        for bed in "${beds[@]}"; do
            out="$work/timed-$(label "$bin")-on-$bed"
            rm -rf "$out"
            summary=$("$bin" simulate --resume "$work/settled-$bed/checkpoint.bin" \
                --steps $((settled + steps)) -q -o "$out" 2>/dev/null)
            contacts=$(echo "$summary" | awk -F'|' '$3 ~ /^ [0-9]+ $/ && NF == 8 { c = $7 } END { gsub(/ /, "", c); print c }')
            times=$(echo "$summary" | awk -F'|' '/^\| \|/ { print $3 "/" $4 "/" $5 "/" $6 }')
            echo "| $round | $own | $bed | $contacts | $times |"
        done
    done
done
