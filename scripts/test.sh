#!/usr/bin/env bash
# Runs every test of mochi: formatting, lints, unit, integration, property, GPU and doc tests.
# Installs what the tests need first: a Rust toolchain's rustfmt and clippy, and (on Debian or
# Ubuntu, as root) Mesa's lavapipe Vulkan driver with ray queries (Mesa >= 25), so the GPU
# backends are tested on the CPU when the machine has no GPU. With CI=true, GPU tests fail
# rather than skip when no adapter is found. Also installs NVRTC 13.0 from PyPI into target/nvrtc
# and compiles the optix feature's device programs with it (no GPU needed), and Open MPI, with
# which a run decomposed over processes is checked (the mpi feature).
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v cargo >/dev/null; then
    echo "error: cargo not found: install Rust (https://rustup.rs) first" >&2
    exit 1
fi
for component in rustfmt clippy; do
    if ! cargo "${component/rustfmt/fmt}" --version >/dev/null 2>&1; then
        rustup component add "$component"
    fi
done

# The archive URI that this machine's apt configuration uses for the suite $1 (deb822 .sources
# files first, then one-line sources.list entries); empty when none names it.
debian_archive() {
    local suite=$1 f
    for f in /etc/apt/sources.list.d/*.sources; do
        [ -e "$f" ] || continue
        awk -v suite="$suite" '
            /^[[:space:]]*$/ { if (uri != "" && hit) { print uri; exit } uri = ""; hit = 0; next }
            /^URIs:/ { uri = $2 }
            /^Suites:/ { for (i = 2; i <= NF; i++) if ($i == suite) hit = 1 }
            END { if (uri != "" && hit) print uri }' "$f"
    done | head -n 1 | grep . && return
    grep -hE "^deb[[:space:]]+(\[[^]]*\][[:space:]]+)?[a-z]+://[^[:space:]]+[[:space:]]+$suite[[:space:]]" \
        /etc/apt/sources.list /etc/apt/sources.list.d/*.list 2>/dev/null |
        sed -E 's/^deb[[:space:]]+(\[[^]]*\][[:space:]]+)?//' | awk '{ print $1; exit }'
}

# lavapipe with VK_KHR_ray_query: Mesa 25 or newer.
mesa_version() { dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || echo 0; }
if command -v dpkg >/dev/null && ! dpkg --compare-versions "$(mesa_version)" ge 25; then
    if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
        echo "warning: cannot install lavapipe (needs root and apt-get); GPU tests need an adapter" >&2
    else
        echo "installing Mesa's lavapipe Vulkan driver for the GPU tests"
        . /etc/os-release
        suite=()
        if [ "${VERSION_CODENAME:-}" = bookworm ]; then
            # bookworm's Mesa 22 has no ray queries; bookworm-backports has Mesa 25. The
            # backports source reuses the archive this machine's apt configuration already names.
            archive=$(debian_archive bookworm)
            if [ -z "$archive" ]; then
                echo "error: no apt source for bookworm found under /etc/apt to add bookworm-backports from" >&2
                exit 1
            fi
            cat > /etc/apt/sources.list.d/mochi-backports.sources <<SOURCES
Types: deb
URIs: $archive
Suites: bookworm-backports
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SOURCES
            suite=(-t bookworm-backports)
        fi
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${suite[@]}" \
            mesa-vulkan-drivers libvulkan1 >/dev/null
    fi
fi

# Open MPI (with libclang, which the `mpi` feature's bindings are generated with), so a run
# decomposed over processes is checked under mpirun.
if ! command -v mpicc >/dev/null || ! ls /usr/lib/llvm-*/lib/libclang.so >/dev/null 2>&1; then
    if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
        echo "warning: cannot install Open MPI and libclang (needs root and apt-get)" >&2
    else
        echo "installing Open MPI and libclang for the mpi feature's checks"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq openmpi-bin libopenmpi-dev \
            libclang-dev >/dev/null
    fi
fi

# NVRTC 13.0 from PyPI, so the optix feature's device programs are compiled here too (no GPU
# needed): a broken .cu cannot land.
nvrtc_dir="$PWD/target/nvrtc"
if [ ! -e "$nvrtc_dir/nvidia/cu13/lib/libnvrtc.so.13" ]; then
    if ! python3 -m pip --version >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-pip >/dev/null
    fi
    echo "installing NVRTC 13.0 (PyPI nvidia-cuda-nvrtc) for the optix device-program check"
    python3 -m pip install --quiet --disable-pip-version-check --break-system-packages \
        --target "$nvrtc_dir" nvidia-cuda-nvrtc==13.0.88 ||
        python3 -m pip install --quiet --disable-pip-version-check \
            --target "$nvrtc_dir" nvidia-cuda-nvrtc==13.0.88
fi
export LD_LIBRARY_PATH="$nvrtc_dir/nvidia/cu13/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

# lavapipe runs each dispatch in the submitting thread rather than waking a pool of its own: the
# tests' scenes are small, their dispatches many, and the test harness already runs one test per
# core (no effect on a real GPU's driver).
export LP_NUM_THREADS="${LP_NUM_THREADS:-0}"
# On a fresh machine (an empty shader cache, as CI's) most of the GPU tests' time is llvmpipe
# compiling the DEM steps' kernels at their first dispatch; at a vector width of 128 bits it
# compiles them in half the time and runs the tests' small scenes as fast (tests/dem.rs from an
# empty cache on the 2-core machine: 245 s at the default 256 bits, 114 s at 128).
export LP_NATIVE_VECTOR_WIDTH="${LP_NATIVE_VECTOR_WIDTH:-128}"

# A clean clone gains nothing from incremental caches, which would double the debug build's size.
if [ "${CI:-}" = true ]; then
    export CARGO_INCREMENTAL=0
fi

cargo fmt --all -- --check
cargo clippy --all-targets --locked -- -D warnings
cargo clippy --all-targets --features optix,mpi --locked -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --locked --quiet
cargo test --locked
cargo test --locked --features optix,mpi --test optix

# Runs decomposed over processes under mpirun equal the runs of one process bit for bit.
bash scripts/mpi-check.sh

# The Python package (python/, a member of the workspace): a debug build of the extension into
# the workspace's target/ (so the library and its dependencies built above are reused), installed
# with pytest into a virtual environment from the machine's configured package index. A failed
# install fails the run.
venv="$PWD/target/py-venv"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check numpy pytest
MATURIN_PEP517_ARGS="--profile dev" \
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps ./python
"$venv/bin/python" -m pytest -q python/tests
# The type stub (python/mochi/__init__.pyi) against the module as built: every name, parameter
# and default (mypy's stubtest; PEP 800's disjoint bases left to newer type checkers).
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check mypy
MYPY_CACHE_DIR="$PWD/target/mypy-cache" "$venv/bin/python" -m mypy.stubtest mochi --ignore-disjoint-bases
