"""What a bug or a lack of memory looks like from Python: a panic in
mochi is a MochiError naming the call, never pyo3's PanicException (a BaseException that
`except Exception` lets through); input that is too large is one ValueError or MemoryError,
never an aborted interpreter."""

import os
import subprocess
import sys
import textwrap

import pytest

import mochi

try:
    import resource
except ImportError:  # not on Windows
    resource = None


@pytest.mark.parametrize("where", ["here", "pool"])
def test_a_panic_is_a_mochi_error_naming_the_call(where):
    # `_panic` panics on purpose: with the interpreter lock held, or in a rayon task.
    with pytest.raises(mochi.MochiError) as caught:
        mochi._mochi._panic(where)
    message = str(caught.value)
    assert "mochi._mochi._panic" in message and "a bug in mochi" in message
    assert "deliberate panic" in message and "lib.rs" in message  # what and where


# Inputs that would panic inside the library are refused as ValueError.
BAD_INFLOWS = {
    "radius beyond f32": "sphere_radii = [0.003, 1e39]",
    "corner beyond f32": "lo = [-1e39, 0.3, 0.85]\nhi = [0.7, 0.7, 0.95]",
}


@pytest.mark.parametrize("table", BAD_INFLOWS.values(), ids=BAD_INFLOWS.keys())
def test_an_inflow_beyond_f32_is_a_value_error(tmp_path, table):
    fields = {"lo": "lo = [0.3, 0.3, 0.85]", "hi": "hi = [0.7, 0.7, 0.95]"}
    for line in table.splitlines():
        fields[line.split(" =")[0]] = line
    fields.setdefault("sphere_radii", "sphere_radius = 0.0005")
    path = tmp_path / "scene.toml"
    path.write_text(
        'scene = "freefall"\nspheres = 10\n[[inflow]]\nrate = 1e6\n' + "\n".join(fields.values())
    )
    with pytest.raises(ValueError, match="inflow"):
        sim = mochi.Simulation(path, backend="cpu")
        sim.step(10)


def test_too_many_mesh_copies_is_a_value_error():
    with pytest.raises(ValueError, match="mesh_copies"):
        mochi.Simulation({"scene": "mesh", "mesh_copies": 4294967295}, backend="cpu")


def run_limited(code, limit_kib=3_000_000):
    """Runs `code` in a fresh interpreter whose address space is limited to `limit_kib` KiB (as
    `ulimit -v` sets it), printing the ValueError or MemoryError it raises; its output and exit
    status."""
    script = "\n".join(
        [
            "import resource",
            f"limit = {limit_kib} * 1024",
            "resource.setrlimit(resource.RLIMIT_AS, (limit, limit))",
            "import numpy as np",
            "import mochi",
            "try:",
            textwrap.indent(textwrap.dedent(code).strip(), "    "),
            "except (ValueError, MemoryError) as e:",
            "    print(type(e).__name__, e)",
        ]
    )
    env = {**os.environ, "RUST_BACKTRACE": "0"}
    return subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600
    )


needs_rlimit = pytest.mark.skipif(resource is None, reason="no resource module (RLIMIT_AS)")


@needs_rlimit
@pytest.mark.parametrize(
    "limit_kib, runs_out_in",
    # The case (ulimit -v 3000000): the float64 arrays and their float32 copies fit,
    # the cpu grid does not; and a tighter limit, under which the copies do not fit either.
    [(3_000_000, "cpu grid"), (1_750_000, "centres")],
)
def test_detecting_more_spheres_than_memory_holds_is_one_error(limit_kib, runs_out_in):
    done = run_limited(
        """
        n = 40_000_000
        centres = np.zeros((n, 3))
        centres[:, 0] = np.arange(n, dtype=np.float64)
        centres[:, 0] *= 3.0
        mochi.detect(centres, np.ones(n), backend="cpu")
        print("no error")
        """,
        limit_kib,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("MemoryError"), done.stdout
    assert runs_out_in in done.stdout, done.stdout
    assert "40000000" in done.stdout and "bytes needed" in done.stdout, done.stdout
    assert done.stdout.count("\n") == 1 and done.stderr == "", done.stderr


@needs_rlimit
def test_a_hopper_larger_than_memory_is_one_error():
    done = run_limited(
        'mochi.Simulation({"scene": "hopper", "spheres": 300_000_000}, backend="cpu")'
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith(("MemoryError", "ValueError")), done.stdout


def test_a_whole_float_count_is_refused_before_anything_is_built():
    with pytest.raises(ValueError, match="takes an integer"):
        mochi.Simulation({"scene": "hopper", "spheres": 3e8}, backend="cpu")
