#!/usr/bin/env bash
# Runs mochi's GPU checks on a lent GPU machine that has no Rust: binaries built elsewhere are
# carried in .bin/ (made by `scripts/gpu-machine.sh pack` on the build machine), Vulkan's loader
# and glvnd as .deb files in .gl/, Open MPI's in .mpi/ where runs over ranks are measured
# (`apt-get download` of openmpi-bin and its libraries). Usage there:
# `bash scripts/gpu-machine.sh run [TEST...]`.
#   pack   build the release binary and the named test binaries (--features optix) into .bin/
#          (in $CARGO_TARGET_DIR where set; PROFILE=dist for the profile of published builds)
#   run    unpack the loaders, then run each carried test binary with optix expected (TEST_ARGS:
#          more arguments for every test binary, e.g. a filter and --nocapture)
#   shell  unpack the loaders, then run the command given (a benchmark of the carried binaries)
set -euo pipefail
cd "$(dirname "$0")/.."
tests=(backends_exact dem motion simulate optix proxy_parity wgpu_compute)
case "${1:-}" in
pack)
    shift
    [ $# -gt 0 ] && tests=("$@")
    profile=${PROFILE:-release}
    cargo build --profile "$profile" --locked --features optix
    mkdir -p .bin
    cp "${CARGO_TARGET_DIR:-target}/$profile/mochi" .bin/mochi
    for t in "${tests[@]}"; do
        exe=$(cargo test --profile "$profile" --locked --features optix --test "$t" --no-run \
            --message-format=json 2>/dev/null |
            python3 -c 'import json,sys
for l in sys.stdin:
    m = json.loads(l)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and "test" in m["target"]["kind"]:
        print(m["executable"])' | tail -n 1)
        cp "$exe" ".bin/test-$t"
    done
    strip .bin/* 2>/dev/null || true
    echo "built into .bin/ ($(du -sh .bin | cut -f1)); the build root was $PWD"
    echo "$PWD" > .bin/build-root
    # The test binaries name the mochi binary under the target folder they were built in.
    realpath "${CARGO_TARGET_DIR:-target}" > .bin/target-dir
    echo "$profile" > .bin/profile
    ;;
run | shell)
    what=$1
    shift
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    # Open MPI for runs over ranks: the machine's own where it has one (its libraries must not
    # be mixed with another release's), else the one carried in .mpi/; shared memory between
    # the processes of one machine (large messages copied once, process to process: `cma`),
    # none of the network transports probed.
    if ! command -v mpirun > /dev/null && compgen -G ".mpi/*.deb" > /dev/null; then
        for f in .mpi/*.deb; do dpkg -x "$f" /; done
    fi
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    export OMPI_MCA_pml=ob1 OMPI_MCA_btl=self,vader OMPI_MCA_mtl=^ofi,psm,psm2
    export OMPI_MCA_btl_vader_single_copy_mechanism=${OMPI_MCA_btl_vader_single_copy_mechanism:-cma}
    ldconfig
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    if [ "$what" = shell ]; then
        exec "$@"
    fi
    [ $# -gt 0 ] && tests=("$@")
    # The test binaries name the build machine's paths (the binary, tests/data): make them here.
    root=$(cat .bin/build-root)
    if [ "$root" != "$PWD" ] && [ ! -e "$root" ]; then
        mkdir -p "$(dirname "$root")"
        ln -s "$PWD" "$root"
    fi
    target=$(cat .bin/target-dir 2>/dev/null || echo "$root/target")
    profile=$(cat .bin/profile 2>/dev/null || echo release)
    mkdir -p "$target/$profile"
    cp .bin/mochi "$target/$profile/mochi"
    # Not CI=true: that expects wgpu-rq, which needs ray queries (lavapipe has them, the H100 not).
    export MOCHI_EXPECT_OPTIX=1
    nvrtc=$(python3 -c 'import nvidia.cuda_nvrtc, os; print(os.path.dirname(nvidia.cuda_nvrtc.__file__))' 2>/dev/null || true)
    [ -n "$nvrtc" ] && export LD_LIBRARY_PATH="$nvrtc/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    status=0
    for t in "${tests[@]}"; do
        echo "== $t"
        # shellcheck disable=SC2086 # TEST_ARGS are words
        (cd "$root" && "$PWD/.bin/test-$t" --test-threads 1 ${TEST_ARGS:-}) || status=1
    done
    exit $status
    ;;
*)
    echo "usage: $0 pack [TEST...] | run [TEST...] | shell COMMAND..." >&2
    exit 2
    ;;
esac
