#!/usr/bin/env bash
# A DEM benchmark of the tree, timed: BENCH is a folder with a scene.toml (and optionally a
# `prepare` script that writes the scene's input files into WORK_DIR). With a settle (the scene's
# `steps`, or SETTLE=N), each mochi binary given first settles the scene, then every binary
# times STEPS more steps (default 2000) from its own settled state and from the first binary's
# (the same state for all: a later binary reads an earlier one's checkpoint). With SETTLE=0 (or a
# BENCH/settle file that says 0) every
# binary times the scene's own steps from its start (STEPS=N: that many; PHASES=K: in runs of K
# steps, each resumed from the last one's checkpoint, a line each, to show where a run's time
# goes as it changes). ROUNDS times (default 2), alternating binaries. Prints one line per timed
# run: binary, start, contacts at the end, and the summary's ms per step (build / DCD / update /
# total; GPU timestamps where the backend has them).
#
# Usage: benches/run.sh BENCH WORK_DIR MOCHI [MOCHI ...]
#   e.g. benches/run.sh benches/hcp_block /tmp/hcp target/release/mochi
#   BACKEND=wgpu-compute (default) | optix | wgpu-rq | cpu; PYTHON=python3 (with NumPy);
#   MESH=FILE for benches/bunny_drop (the Stanford bunny, not in the tree)
set -euo pipefail
usage="usage: run.sh BENCH WORK_DIR MOCHI [MOCHI ...]"
bench=$(cd "${1:?$usage}" && pwd)
work=${2:?$usage}
shift 2
[ $# -ge 1 ] || { echo "$usage" >&2; exit 2; }
backend=${BACKEND:-wgpu-compute}
rounds=${ROUNDS:-2}
mkdir -p "$work"
cp "$bench/scene.toml" "$work/scene.toml"
[ -x "$bench/prepare" ] && "$bench/prepare" "$work"

scene_steps=$(sed -n 's/^steps = //p' "$bench/scene.toml")
# BENCH/settle, where present, holds the default SETTLE (0: timed from the start).
default_settle=$(cat "$bench/settle" 2>/dev/null || echo "$scene_steps")
settled=${SETTLE:-$default_settle}
label() { basename "$1"; }
contacts_of() { awk -F'|' '$3 ~ /^ [0-9]+ $/ && NF == 8 { c = $7 } END { gsub(/ /, "", c); print c }'; }
times_of() { awk -F'|' '/^\| \|/ { print $3 "/" $4 "/" $5 "/" $6 }'; }
row() { # round, binary, start, summary
    echo "| $1 | $2 | $3 | $(echo "$4" | contacts_of) | $(echo "$4" | times_of) |"
}
header() {
    echo "| round | binary | start | contacts | build / DCD / update / total [ms] |"
    echo "| --- | --- | --- | --- | --- |"
}

if [ "$settled" = 0 ]; then
    steps=${STEPS:-$scene_steps}
    phase=${PHASES:-$steps}
    [ "$phase" -gt 0 ] || { echo "PHASES must be a positive number of steps" >&2; exit 2; }
    header
    for round in $(seq 1 "$rounds"); do
        for bin in "$@"; do
            out="$work/timed-$(label "$bin")"
            at=0
            while [ "$at" -lt "$steps" ]; do
                next=$((at + phase < steps ? at + phase : steps))
                from=(simulate "$work/scene.toml")
                start="scene"
                if [ "$at" -gt 0 ]; then
                    from=(simulate --resume "$out-$at/checkpoint.bin")
                    start="step $at"
                fi
                rm -rf "$out-$next"
                summary=$("$bin" "${from[@]}" --backend "$backend" -q --steps "$next" \
                    -o "$out-$next" 2>/dev/null)
                [ "$phase" -lt "$steps" ] && start="$start to $next"
                row "$round" "$(label "$bin")" "$start" "$summary"
                at=$next
            done
        done
    done
    exit 0
fi

steps=${STEPS:-2000}
for bin in "$@"; do
    echo "settling with $(label "$bin") ($backend)"
    "$bin" simulate "$work/scene.toml" --backend "$backend" -q --overwrite --steps "$settled" \
        -o "$work/settled-$(label "$bin")" 2>&1 | grep -E '^\| [a-z]|^scene'
done
first=$(label "$1")
header
for round in $(seq 1 "$rounds"); do
    for bin in "$@"; do
        own=$(label "$bin")
        beds=("$own")
        [ "$own" = "$first" ] || beds+=("$first")
        for bed in "${beds[@]}"; do
            out="$work/timed-$own-on-$bed"
            rm -rf "$out"
            summary=$("$bin" simulate --resume "$work/settled-$bed/checkpoint.bin" \
                --backend "$backend" --steps $((settled + steps)) -q -o "$out" 2>/dev/null)
            row "$round" "$own" "settled by $bed" "$summary"
        done
    done
done
