#!/usr/bin/env bash
# Checks runs decomposed over processes under mpirun (the mpi feature) against the same runs
# in one process, bit for bit: examples/mpi_pour on 2 and 4 ranks (--check compares with the
# whole run), and `mochi simulate` on 3 ranks, new and resumed on 2, whose files must equal
# those of one process byte for byte, whose frames in pieces draw as one process's and whose
# checkpoints in pieces resume as one process's; a run of clumps on 3 processes, resumed on 2,
# byte for byte too; and a run on wgpu-compute (lavapipe) over 2 processes. Needs Open MPI
# (scripts/test.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --locked --features optix,mpi --example mpi_pour
cargo build --locked -p mochi-cli --features optix,mpi
# Open MPI oversubscribes the cores it is given; as root it must be told that is meant.
if [ "$(id -u)" = 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
for ranks in 2 4; do
    mpirun --oversubscribe -np "$ranks" target/debug/examples/mpi_pour 400 2000 --check
done
work=target/mpi-check
rm -rf "$work"
run=(simulate --scene pour -n 400 --frame-every 500 --backend cpu -q)
target/debug/mochi "${run[@]}" --steps 1000 -o "$work/one"
mpirun --oversubscribe -np 3 target/debug/mochi "${run[@]}" --steps 1000 -o "$work/ranks"
cp -r "$work/one" "$work/one-resumed"
cp -r "$work/ranks" "$work/ranks-resumed"
target/debug/mochi simulate --resume "$work/one-resumed/checkpoint.bin" --steps 1500 -q
mpirun --oversubscribe -np 2 target/debug/mochi simulate \
    --resume "$work/ranks-resumed/checkpoint.bin" --steps 1500 -q
for pair in "one ranks" "one-resumed ranks-resumed"; do
    set -- $pair
    for f in "$work/$1"/*; do
        cmp "$f" "$work/$2/$(basename "$f")"
    done
done
echo "mochi simulate on 3 processes (and resumed on 2) wrote one process's files byte for byte"
# Frames and checkpoints in pieces (frame_pieces, checkpoint_pieces): each process writes its
# own spheres' piece and nothing is gathered; drawn, the pieces of each frame are one process's
# frame, pixel for pixel; resumed on 2 processes from the checkpoint in pieces, and on one to
# write it whole, the checkpoint is one process's byte for byte.
mpirun --oversubscribe -np 3 target/debug/mochi "${run[@]}" --steps 1000 \
    --set frame_pieces=true --set checkpoint_pieces=true --checkpoint-every 500 -o "$work/pieces"
# The end's checkpoint is the last one of the run, not written again into a folder of its own.
test -d "$work/pieces/checkpoint_00001000" && test ! -e "$work/pieces/checkpoint_00000500"
mpirun --oversubscribe -np 2 target/debug/mochi simulate \
    --resume "$work/pieces/checkpoint.bin" --steps 1500 -q
test -d "$work/pieces/checkpoint_00001500" && test ! -e "$work/pieces/checkpoint_00001000"
draw=(render --renderer cpu --size 160x120 --color-by speed)
target/debug/mochi "${draw[@]}" "$work/one-resumed" -o "$work/one-pictures" > /dev/null
target/debug/mochi "${draw[@]}" "$work/pieces" -o "$work/pieces-pictures" > /dev/null
test "$(ls "$work/pieces"/frame_*.pvtu | wc -l)" = 4
for f in "$work/one-pictures"/*.png; do
    cmp "$f" "$work/pieces-pictures/$(basename "$f")"
done
target/debug/mochi simulate --resume "$work/pieces/checkpoint.bin" --steps 1500 -q \
    --set frame_pieces=false --set checkpoint_pieces=false
cmp "$work/pieces/checkpoint.bin" "$work/one-resumed/checkpoint.bin"
test ! -e "$work/pieces/checkpoint_00001500"
echo "mochi simulate on 3 processes (resumed on 2) wrote frames in pieces that draw as one process's"
echo "and checkpoints in pieces that resume as one process's"
# Clumps (the gravel drum: tetrahedra, trimers and rods turning in a mesh drum) on 3 processes,
# frames and checkpoints in pieces asked for: a run of clumps writes them whole, and its files
# are one process's byte for byte.
clumps=(simulate --scene gravel -n 120 --steps 600 --frame-every 300 --backend cpu -q
    --set frame_pieces=true --set checkpoint_pieces=true)
target/debug/mochi "${clumps[@]}" -o "$work/clumps-one" > /dev/null
mpirun --oversubscribe -np 3 target/debug/mochi "${clumps[@]}" -o "$work/clumps-ranks" > /dev/null
target/debug/mochi simulate --resume "$work/clumps-one/checkpoint.bin" --steps 900 -q > /dev/null
mpirun --oversubscribe -np 2 target/debug/mochi simulate \
    --resume "$work/clumps-ranks/checkpoint.bin" --steps 900 -q > /dev/null
test -e "$work/clumps-one/clumps_00000900.vtu"
for f in "$work/clumps-one"/*; do
    cmp "$f" "$work/clumps-ranks/$(basename "$f")"
done
echo "mochi simulate of clumps on 3 processes (resumed on 2) wrote one process's files byte for byte"
# On a GPU backend (lavapipe here) each process steps its slab on its own device: the run must
# finish and report each rank's share.
shares=$(mpirun --oversubscribe -np 2 target/debug/mochi simulate --scene pour -n 400 \
    --backend wgpu-compute --steps 200 --frame-every 0 -q -o "$work/gpu")
grep -q "^| 1 | " <<< "$shares" || { echo "no share of rank 1 in: $shares" >&2; exit 1; }
echo "mochi simulate on 2 processes of wgpu-compute reported each rank's share"
rm -rf "$work"
