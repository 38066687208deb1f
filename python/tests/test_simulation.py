"""mochi.Simulation on the cpu backend: free fall against the closed form, a small pile's energy,
checkpoint and resume bit for bit, bad scenes, progress and Ctrl-C, frames read back."""

import _thread
import math
import threading

import numpy as np
import pytest

import mochi

GRAVITY = 9.81
DENSITY = 500.0


def one_sphere_scene(tmp_path, x0, v0, r=0.05):
    """A single sphere far from the walls of a large box, from a frame CSV."""
    start = tmp_path / "start.csv"
    start.write_text("x,y,z,r,vx,vy,vz\n" + ",".join(map(str, [*x0, r, *v0])) + "\n")
    return {
        "scene": "input",
        "input": start,
        "box_lo": [-100.0, -100.0, -100.0],
        "box_hi": [100.0, 100.0, 100.0],
        "gravity": [0.0, 0.0, -GRAVITY],
        "density": DENSITY,
    }


def test_a_falling_sphere_follows_the_closed_form(tmp_path):
    x0 = np.array([0.5, -0.25, 2.0])
    v0 = np.array([0.3, 0.0, 1.5])
    sim = mochi.Simulation(one_sphere_scene(tmp_path, x0, v0), backend="cpu")
    assert sim.backend == "cpu" and len(sim) == 1 and sim.step_count == 0
    n = 2000
    sim.step(n)
    dt = np.float32(sim.dt)
    t = n * float(dt)
    assert sim.step_count == n and sim.time == pytest.approx(t, rel=1e-12)
    g = np.array([0.0, 0.0, -GRAVITY])
    exact = x0 + v0 * t + g * t * t / 2
    # Semi-implicit Euler (v += g dt, then x += v dt) is ahead of the closed form by g t dt / 2;
    # float32 adds a rounding of the velocity per step (the position keeps every displacement).
    lead = g * t * float(dt) / 2
    rounding = n * np.finfo(np.float32).eps * np.abs(exact).max()
    position = sim.positions[0].astype(np.float64)
    np.testing.assert_allclose(position, exact, rtol=0, atol=np.abs(lead).max() + rounding)
    np.testing.assert_allclose(position - exact, lead, rtol=0, atol=rounding)
    np.testing.assert_allclose(sim.velocities[0], v0 + g * t, rtol=0, atol=1e-4)
    np.testing.assert_array_equal(sim.angular_velocities, np.zeros((1, 3), np.float32))
    assert sim.contacts == 0


def test_a_slow_sphere_far_out_moves_by_every_step(tmp_path):
    # 1 mm/s along each axis for 10^4 steps of 1e-7 s at 50 m from the origin: 1 um, where each
    # step's 1e-10 m is far below float32's spacing there (3.8e-6 m). The positions are float64:
    # each centre plus the residual that keeps every displacement.
    x0 = np.array([50.0, -50.0, 50.0])
    v0 = np.array([1e-3, -1e-3, 1e-3])
    scene = one_sphere_scene(tmp_path, x0, v0) | {"gravity": [0.0, 0.0, 0.0], "dt": 1e-7}
    sim = mochi.Simulation(scene, backend="cpu")
    assert sim.positions.dtype == np.float64
    sim.step(10_000)
    np.testing.assert_allclose(sim.positions[0] - x0, v0 * 1e-3, rtol=1e-3)
    path = tmp_path / "frame.csv"
    sim.write_frame(path)
    np.testing.assert_array_equal(mochi.read_frame(path)["positions"], sim.positions)


def energy(sim):
    """Kinetic (translation and rotation) plus gravitational energy of the spheres."""
    r = sim.radii.astype(np.float64)
    m = DENSITY * 4.0 / 3.0 * math.pi * r**3
    v = sim.velocities.astype(np.float64)
    w = sim.angular_velocities.astype(np.float64)
    z = sim.positions[:, 2].astype(np.float64)
    inertia = 0.4 * m * r * r
    return (
        0.5 * (m * (v * v).sum(1)).sum()
        + 0.5 * (inertia * (w * w).sum(1)).sum()
        + (m * GRAVITY * z).sum()
    )


def test_a_small_pile_settles_without_gaining_energy():
    sim = mochi.Simulation(
        {"scene": "pour", "spheres": 300, "density": DENSITY}, backend="cpu"
    )
    start = energy(sim)
    lo, hi = sim.positions.min(0), sim.positions.max(0)
    before = start
    for _ in range(5):
        sim.step(400)
        now = energy(sim)
        # Contacts and walls only take energy out (the springs' own energy is not counted).
        assert now <= before + 1e-6 * abs(start)
        before = now
    assert now < start
    assert sim.contacts > 0
    assert np.isfinite(sim.positions).all() and np.isfinite(sim.velocities).all()
    assert sim.positions[:, 2].min() > 0.0
    assert (sim.positions.max(0) - sim.positions.min(0) >= (hi - lo) * 0.5).all()


def test_checkpoint_and_resume_continue_bit_for_bit(tmp_path):
    scene = {"scene": "pour", "spheres": 300, "seed": 7}
    straight = mochi.Simulation(scene, backend="cpu")
    straight.step(1200)

    first = mochi.Simulation(scene, backend="cpu")
    first.step(800)
    assert first.contacts > 0  # the checkpoint holds a contact history
    first.checkpoint(tmp_path / "run.bin")
    resumed = mochi.Simulation.resume(tmp_path / "run.bin", backend="cpu")
    assert resumed.step_count == 800 and resumed.dt == first.dt
    resumed.step(400)

    assert resumed.step_count == straight.step_count == 1200
    assert resumed.time == straight.time
    assert resumed.contacts == straight.contacts
    for name in ["positions", "velocities", "angular_velocities", "radii", "materials"]:
        np.testing.assert_array_equal(getattr(resumed, name), getattr(straight, name), name)


@pytest.mark.parametrize(
    "scene, words",
    [
        ({"spherez": 10}, "spherez"),
        ({"spheres": "many"}, "spheres"),
        ({"spheres": -1}, "spheres"),
        ({"scene": "nowhere"}, "nowhere"),
        ({"restitution": [1, 2]}, "restitution"),
        ({"contact_time": 1e-3}, "contact_time"),
        ({"scene": "freefall", "dt": 1.0}, "time step"),
        ({"spheres": 10**30}, "spheres"),
        ({"spheres": None}, "spheres"),
        ({"bad key": 1}, "bad key"),
        ({"scene": "mesh", "spheres": 10}, "spheres"),
    ],
)
def test_bad_scene_keys_and_values_are_value_errors_naming_them(scene, words):
    with pytest.raises(ValueError, match=words):
        mochi.Simulation(scene, backend="cpu")


def test_bad_arguments_are_errors():
    with pytest.raises(ValueError, match="backend"):
        mochi.Simulation({"scene": "freefall", "spheres": 10}, backend="abacus")
    with pytest.raises(TypeError):
        mochi.Simulation(42)
    with pytest.raises(OSError):
        mochi.Simulation("/nonexistent/scene.toml")
    with pytest.raises(OSError):
        mochi.Simulation.resume("/nonexistent/run.bin", backend="cpu")


def test_a_scene_file_gives_the_same_run_as_its_dict(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text('scene = "freefall"\nspheres = 50\nseed = 3\n')
    from_file = mochi.Simulation(path, backend="cpu")
    from_dict = mochi.Simulation({"scene": "freefall", "spheres": 50, "seed": 3}, backend="cpu")
    for sim in (from_file, from_dict):
        sim.step(30)
    np.testing.assert_array_equal(from_file.positions, from_dict.positions)
    assert from_file.dt == from_dict.dt


def test_progress_gets_the_increments():
    sim = mochi.Simulation({"scene": "freefall", "spheres": 20}, backend="cpu")
    calls = []
    sim.step(250, progress=calls.append)
    # Calls paced at about a quarter second: 10 steps first, then at most four times the last.
    assert sum(calls) == 250 and calls[0] == 10 and all(c > 0 for c in calls)
    assert all(b <= 4 * a for a, b in zip(calls, calls[1:])), calls
    before = list(calls)
    sim.step(0, progress=calls.append)
    assert calls == before and sim.step_count == 250


def test_ctrl_c_stops_between_batches():
    sim = mochi.Simulation({"scene": "freefall", "spheres": 20}, backend="cpu")
    n = 10**8
    calls = []
    ctrl_c = threading.Timer(0.5, _thread.interrupt_main)
    ctrl_c.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            sim.step(n, progress=calls.append)
    finally:
        ctrl_c.cancel()
    # Stopped between calls of the step: the steps taken are the ones reported.
    assert 0 < sim.step_count < n and sim.step_count == sum(calls)


@pytest.mark.parametrize("ext", ["vtu", "csv", "npy"])
def test_frames_read_back_as_written(tmp_path, ext):
    sim = mochi.Simulation({"scene": "pour", "spheres": 200}, backend="cpu")
    sim.step(900)
    path = tmp_path / f"frame.{ext}"
    sim.write_frame(path)
    frame = mochi.read_frame(path)
    for name in ["positions", "velocities", "angular_velocities", "radii", "materials"]:
        np.testing.assert_array_equal(frame[name], getattr(sim, name), name)
    assert frame["materials"].dtype == np.uint8 and not frame["materials"].any()
    if ext == "vtu":
        assert frame["step"] == 900 and frame["time"] == pytest.approx(sim.time)
    if ext == "npy":
        table = np.load(path)
        assert table.dtype == np.float64 and table.shape == (200, 11)
        np.testing.assert_array_equal(table[:, :3], sim.positions)
        np.testing.assert_array_equal(table[:, 3], sim.radii)
        np.testing.assert_array_equal(table[:, 4:7], sim.velocities)
        np.testing.assert_array_equal(table[:, 7:10], sim.angular_velocities)
        np.testing.assert_array_equal(table[:, 10], sim.materials)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left


def test_a_frame_of_unknown_type_is_refused(tmp_path):
    sim = mochi.Simulation({"scene": "freefall", "spheres": 10}, backend="cpu")
    with pytest.raises(ValueError, match="frame file type"):
        sim.write_frame(tmp_path / "frame.txt")
    assert list(tmp_path.iterdir()) == []


def test_the_default_scene_is_pour():
    assert "pour" in repr(mochi.Simulation(backend="cpu"))


# The count follows the flows.

FLOWS_TOML = """scene = "freefall"
spheres = 200
seed = 5
{inflow}
{outflow}
"""
INFLOW_TOML = """[[inflow]]
lo = [0.3, 0.3, 0.85]
hi = [0.7, 0.7, 0.95]
rate = 200000
sphere_radius = 0.0005
"""
# The lower half of the box, where about half of freefall's spheres start.
OUTFLOW_TOML = """[[outflow]]
lo = [0.0, 0.0, 0.0]
hi = [1.0, 1.0, 0.5]
"""


def flow_backends():
    """cpu, and wgpu-compute where it runs (its flows stay on the device)."""
    available = {e["name"]: e for e in mochi.backends()}
    return ["cpu"] + (["wgpu-compute"] if available["wgpu-compute"]["available"] else [])


@pytest.mark.parametrize("backend", flow_backends())
@pytest.mark.parametrize("inflow, outflow", [(True, False), (False, True), (True, True)])
def test_len_follows_inflows_and_outflows(tmp_path, backend, inflow, outflow):
    path = tmp_path / "scene.toml"
    path.write_text(
        FLOWS_TOML.format(
            inflow=INFLOW_TOML if inflow else "", outflow=OUTFLOW_TOML if outflow else ""
        )
    )
    sim = mochi.Simulation(path, backend=backend)
    assert len(sim) == 200 and sim.positions.shape == (200, 3)
    sim.step(300)
    # Asked before anything is read back (the flows' counts), then after (the particles).
    counted = len(sim)
    for name in ["positions", "velocities", "angular_velocities"]:
        assert getattr(sim, name).shape == (counted, 3), name
    assert sim.radii.shape == (counted,)
    assert len(sim) == counted and f"spheres={counted}," in repr(sim)
    if inflow and not outflow:
        assert counted > 200
    if outflow and not inflow:
        assert 0 < counted < 200


# Tables, NumPy values and read-only arrays.

INFLOW = {
    "lo": [0.3, 0.3, 0.85],
    "hi": [0.7, 0.7, 0.95],
    "rate": 200000,
    "sphere_radius": 0.0005,
}
OUTFLOW = {"lo": [0.0, 0.0, 0.0], "hi": [1.0, 1.0, 0.5]}


def run_of(scene, steps=300):
    """The positions and count after `steps` steps of `scene` on the cpu backend."""
    sim = mochi.Simulation(scene, backend="cpu")
    sim.step(steps)
    return len(sim), sim.positions


@pytest.mark.parametrize("inflow", [[INFLOW], INFLOW], ids=["list", "lone dict"])
def test_flow_tables_in_the_dict_give_the_run_of_the_scene_file(tmp_path, inflow):
    path = tmp_path / "scene.toml"
    path.write_text(FLOWS_TOML.format(inflow=INFLOW_TOML, outflow=OUTFLOW_TOML))
    from_file = run_of(path)
    scene = {"scene": "freefall", "spheres": 200, "seed": 5, "inflow": inflow}
    from_dict = run_of({**scene, "outflow": (OUTFLOW,)})
    assert from_dict[0] == from_file[0] != 200
    np.testing.assert_array_equal(from_dict[1], from_file[1])


def test_a_wall_table_with_a_nested_table_in_the_dict(tmp_path):
    # A unit square of two triangles, turned upright about x and moved to y = 0.5: a wall
    # across the box that half of freefall's spheres start beyond.
    mesh = tmp_path / "square.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    wall = {"mesh": mesh, "rotate": {"axis": [1, 0, 0], "degrees": 90}, "translate": [0, 0.5, 0]}
    path = tmp_path / "scene.toml"
    path.write_text(
        'scene = "freefall"\nspheres = 100\n[[wall]]\nmesh = "square.obj"\n'
        "rotate = { axis = [1, 0, 0], degrees = 90 }\ntranslate = [0, 0.5, 0]\n"
    )
    from_file = run_of(path, steps=50)
    for given in [wall, [wall]]:
        from_dict = run_of({"scene": "freefall", "spheres": 100, "wall": given}, steps=50)
        np.testing.assert_array_equal(from_dict[1], from_file[1])
    with pytest.raises(ValueError, match="scene: scene key wall.0.spin: unknown field `spin`"):
        mochi.Simulation({"scene": "freefall", "wall": {"mesh": mesh, "spin": 1}}, backend="cpu")
    with pytest.raises(ValueError, match="str"):
        mochi.Simulation({"scene": "freefall", "wall": {1: mesh}}, backend="cpu")


def test_numpy_scalars_and_arrays_are_scene_values():
    plain = {
        "scene": "freefall",
        "spheres": 60,
        "seed": 3,
        "density": 500.0,
        "csv": True,
        "box_lo": [0.0, 0.0, 0.0],
        "box_hi": [1.0, 1.0, 1.0],
        "gravity": [0.0, 0.0, -9.75],
        "inflow": [INFLOW],
    }
    numpy = {
        "scene": np.str_("freefall"),
        "spheres": np.int64(60),
        "seed": np.uint32(3),
        "density": np.float32(500.0),
        "csv": np.bool_(True),
        "box_lo": np.zeros(3),
        "box_hi": np.ones(3, dtype=np.float32),
        "gravity": [np.float64(0.0), np.array(0.0), np.array(-9.75)],
        "inflow": [{**INFLOW, "rate": np.int32(200000), "lo": np.array(INFLOW["lo"])}],
    }
    a, b = run_of(plain, steps=100), run_of(numpy, steps=100)
    assert a[0] == b[0]
    np.testing.assert_array_equal(a[1], b[1])
    masked = np.ma.masked_array([0.0, 0.0, 0.0], mask=[True, False, False])
    with pytest.raises(ValueError, match="box_lo.*mask"):
        mochi.Simulation({"scene": "freefall", "box_lo": masked}, backend="cpu")


@pytest.mark.parametrize("value", [3e8, 100.0, np.float64(100)])
def test_a_whole_float_for_an_integer_key_is_refused_naming_it(value):
    with pytest.raises(ValueError, match=r'"spheres" takes an integer, not the float'):
        mochi.Simulation({"scene": "freefall", "spheres": value}, backend="cpu")
    # As a scene file's is; a whole float for a float key, and an int for one, are values.
    sim = mochi.Simulation({"scene": "freefall", "spheres": 10, "density": 500}, backend="cpu")
    assert len(sim) == 10


def test_the_arrays_are_read_only_snapshots_of_their_step():
    sim = mochi.Simulation({"scene": "freefall", "spheres": 50}, backend="cpu")
    names = ["positions", "velocities", "angular_velocities", "radii", "materials"]
    before = {name: getattr(sim, name) for name in names}
    for name, array in before.items():
        assert not array.flags.writeable, name
        assert getattr(sim, name) is array, name  # one array per step, not a copy per read
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
    kept = before["positions"].copy()
    sim.step(20)
    np.testing.assert_array_equal(before["positions"], kept)  # the old step's, unchanged
    assert sim.positions is not before["positions"]
    assert not (sim.positions == kept).all()


def test_a_pour_of_clumps_runs_and_resumes_bit_for_bit(tmp_path):
    # 100 grains, each a tetrahedron of four spheres or a dimer of two, on the cpu backend.
    scene = {
        "scene": "pour",
        "spheres": 100,
        "seed": 5,
        "clump": [{"shape": "tetrahedron"}, {"shape": "dimer"}],
    }
    straight = mochi.Simulation(scene)
    n = len(straight)
    assert 200 < n < 400 and n % 2 == 0
    straight.step(1000)
    first = mochi.Simulation(scene)
    first.step(600)
    first.checkpoint(tmp_path / "run.bin")
    resumed = mochi.Simulation.resume(tmp_path / "run.bin")
    resumed.step(400)
    for name in ["positions", "velocities", "angular_velocities", "radii"]:
        np.testing.assert_array_equal(getattr(resumed, name), getattr(straight, name), name)
    clumps = straight.clumps
    assert clumps["positions"].shape == (100, 3) and clumps["orientations"].shape == (100, 4)
    np.testing.assert_allclose(np.linalg.norm(clumps["orientations"], axis=1), 1.0, atol=1e-12)
    # Each sphere's clump: the clumps' spheres first, in order; each centre within its clump.
    owners = clumps["spheres"]
    assert owners.shape == (n,) and owners[0] == 0 and owners[-1] == 99
    assert (np.diff(owners) >= 0).all()
    reach = np.linalg.norm(straight.positions - clumps["positions"][owners], axis=1)
    assert (reach < 2 * straight.radii).all()
    for name in clumps:
        np.testing.assert_array_equal(resumed.clumps[name], clumps[name], name)
    # A lone dict is the array of one table; a bad shape is refused naming it.
    rods = mochi.Simulation({"scene": "freefall", "spheres": 10, "clump": {"shape": "rod"}})
    assert len(rods) == 40
    with pytest.raises(ValueError, match="cube"):
        mochi.Simulation({"scene": "freefall", "spheres": 10, "clump": {"shape": "cube"}})


@pytest.mark.parametrize("variable", ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE"])
def test_one_of_several_mpi_processes_is_told_to_run_one(monkeypatch, variable):
    # Each process of `mpirun -np 2 python …` would run the whole scene: refused, saying so.
    monkeypatch.setenv(variable, "2")
    with pytest.raises(mochi.MochiError, match="one of 2 that an MPI launcher started"):
        mochi.Simulation({"scene": "pour", "spheres": 50})
    monkeypatch.setenv(variable, "1")
    assert len(mochi.Simulation({"scene": "pour", "spheres": 50})) == 50
