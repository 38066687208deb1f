"""Scripting a run from Python: scene keys as keyword arguments, a run from arrays, closing a
run, the version, detection of one (N, 4) array, and errors that name the scene key."""

import importlib.metadata
import os

import numpy as np
import pytest

import mochi


def test_scene_keys_as_keyword_arguments_are_set_over_the_scene():
    a = mochi.Simulation({"scene": "freefall", "spheres": 30}, backend="cpu", spheres=40, friction=0.2)
    assert len(a) == 40
    b = mochi.Simulation("freefall", backend="cpu", spheres=40, friction=0.2)
    a.step(20)
    b.step(20)
    np.testing.assert_array_equal(a.positions, b.positions)
    # In their tables as well as by their short forms.
    c = mochi.Simulation(backend="cpu", source={"scene": "freefall", "spheres": 40}, material={"friction": 0.2})
    c.step(20)
    np.testing.assert_array_equal(a.positions, c.positions)


@pytest.mark.parametrize(
    "keys, words",
    [
        ({"friction": "x"}, 'scene: scene key material.friction (friction): invalid type: string "x"'),
        ({"sphers": 3}, "scene key sphers: is not a key of a scene: did you mean spheres?"),
        ({"gravity": [0, 0]}, "scene key domain.gravity (gravity): invalid length 2"),
    ],
)
def test_a_bad_scene_key_is_named_without_toml_syntax(keys, words):
    with pytest.raises(ValueError) as error:
        mochi.Simulation("freefall", spheres=10, backend="cpu", **keys)
    message = str(error.value)
    assert words in message, message
    assert "TOML" not in message and "^" not in message, message


def test_a_run_from_arrays_is_the_run_of_the_same_spheres_from_a_file(tmp_path):
    poured = mochi.Simulation("pour", spheres=200, backend="cpu")
    poured.step(300)
    frame = tmp_path / "frame.npy"
    poured.write_frame(frame)
    f = mochi.read_frame(frame)
    assert np.abs(f["velocities"]).max() > 0, "the spheres move: their velocities are compared"
    from_file = mochi.Simulation({"scene": "input", "input": str(frame)}, backend="cpu")
    from_arrays = mochi.Simulation.from_arrays(
        f["positions"],
        f["radii"],
        velocities=f["velocities"],
        angular_velocities=f["angular_velocities"],
        materials=f["materials"],
        backend="cpu",
    )
    for name in ["positions", "velocities", "angular_velocities", "radii", "materials"]:
        np.testing.assert_array_equal(getattr(from_arrays, name), getattr(from_file, name), name)
    from_file.step(100)
    from_arrays.step(100)
    for name in ["positions", "velocities", "angular_velocities"]:
        np.testing.assert_array_equal(getattr(from_arrays, name), getattr(from_file, name), name)
    assert repr(from_arrays).startswith("Simulation(scene=\"input\", spheres=200")


def test_a_run_from_arrays_takes_scene_keys_and_refuses_bad_arrays():
    positions = np.array([[0.5, 0.5, 0.5], [0.5, 0.5, 0.53]])
    radii = np.array([0.01, 0.01])
    sim = mochi.Simulation.from_arrays(
        positions, radii, backend="cpu", box_lo=[0, 0, 0], box_hi=[1, 1, 1], gravity=[0, 0, 0]
    )
    # float64 positions kept as a float32 centre and its residual.
    np.testing.assert_allclose(sim.positions, positions, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(sim.velocities, np.zeros((2, 3), np.float32))
    start = sim.positions
    sim.step(10)
    np.testing.assert_array_equal(sim.positions, start)  # no gravity, apart: at rest
    with pytest.raises(ValueError, match=r"radii must have shape \(2\), not \[3\]"):
        mochi.Simulation.from_arrays(positions, np.ones(3) * 0.01, backend="cpu")
    with pytest.raises(ValueError, match=r"velocities must have shape \(2, 3\)"):
        mochi.Simulation.from_arrays(positions, radii, velocities=np.zeros((2, 2)), backend="cpu")
    with pytest.raises(ValueError, match="sphere 1: material 300"):
        mochi.Simulation.from_arrays(positions, radii, materials=np.array([0, 300]), backend="cpu")
    with pytest.raises(ValueError, match="material 1, but the scene has 1 material"):
        mochi.Simulation.from_arrays(positions, radii, materials=np.array([0, 1]), backend="cpu")
    with pytest.raises(ValueError, match="sphere 0"):
        mochi.Simulation.from_arrays(positions * np.nan, radii, backend="cpu")
    with pytest.raises(ValueError, match="outside the box"):
        mochi.Simulation.from_arrays(positions, radii, backend="cpu", box_lo=[0, 0, 0], box_hi=[0.4, 1, 1])
    # Keys of another scene than a run from arrays (scene `input`).
    with pytest.raises(ValueError, match="spheres"):
        mochi.Simulation.from_arrays(positions, radii, backend="cpu", spheres=10)


def test_a_closed_run_lets_its_backend_go_and_refuses_every_call():
    with mochi.Simulation("freefall", spheres=10, backend="cpu") as sim:
        sim.step(2)
        assert not sim.closed
    assert sim.closed
    assert repr(sim) == "Simulation(closed, step=2)"
    for call in [lambda: sim.step(1), lambda: sim.positions, lambda: len(sim), lambda: sim.dt]:
        with pytest.raises(mochi.MochiError, match="closed"):
            call()
    sim.close()  # again: nothing happens
    # An exception of the block goes on, and the run is closed.
    with pytest.raises(KeyError):
        with mochi.Simulation("freefall", spheres=10, backend="cpu") as other:
            raise KeyError("out")
    assert other.closed


def test_a_scene_is_named_where_no_file_has_that_name(tmp_path, monkeypatch):
    assert mochi.Simulation("hopper", spheres=50, backend="cpu").material_names == ["default"]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "drum").write_text('scene = "freefall"\nspheres = 7\n')
    assert len(mochi.Simulation("drum", backend="cpu")) == 7, "the file named drum"
    with pytest.raises(ValueError, match=r'unknown scene "teapot": use freefall, .*; nor is there a scene file teapot'):
        mochi.Simulation("teapot", backend="cpu")
    with pytest.raises(OSError, match="teapot.toml"):
        mochi.Simulation("teapot.toml", backend="cpu")


def test_steps_walls_and_positions_out_of_range_are_value_errors():
    sim = mochi.Simulation("pour", spheres=50, backend="cpu")
    with pytest.raises(ValueError, match="step takes a number of steps from 0, got -1"):
        sim.step(-1)
    with pytest.raises(ValueError, match="cannot set the motion of wall -1: walls are numbered from 0"):
        sim.set_wall_motion(-1, velocity=[1.0, 0.0, 0.0])
    nan = sim.positions.copy()
    nan[3] = np.nan
    with pytest.raises(ValueError, match=r"sphere 3: its position \[NaN, NaN, NaN\] is not finite"):
        sim.positions = nan
    assert sim.step_count == 0


def test_the_version_is_the_package_s():
    assert mochi.__version__ == importlib.metadata.version("mochi")


def test_detect_takes_one_array_of_x_y_z_r():
    rng = np.random.default_rng(3)
    centres = rng.random((500, 3), dtype=np.float32)
    radii = rng.uniform(0.01, 0.05, 500).astype(np.float32)
    rows = np.hstack([centres, radii[:, None]])
    expected = mochi.detect(centres, radii, backend="cpu")
    assert len(expected) > 0
    np.testing.assert_array_equal(mochi.detect(rows, backend="cpu"), expected)
    np.testing.assert_array_equal(mochi.detect(rows.astype(np.float64), backend="cpu"), expected)
    detector = mochi.Detector(backend="cpu")
    detector.build(rows)
    np.testing.assert_array_equal(detector.pairs(), expected)
    with pytest.raises(ValueError, match=r"one \(N, 4\) array of x, y, z, r, not shape \[500, 3\]"):
        mochi.detect(centres, backend="cpu")


def test_the_kinetic_energy_of_an_elastic_frictionless_impact_is_kept():
    positions = np.array([[0.4, 0.5, 0.5], [0.6, 0.5, 0.5]])
    radii = np.array([0.05, 0.05])
    velocities = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    sim = mochi.Simulation.from_arrays(
        positions,
        radii,
        velocities=velocities,
        backend="cpu",
        box_lo=[0, 0, 0],
        box_hi=[1, 1, 1],
        gravity=[0, 0, 0],
        contact="linear",
        restitution=1.0,
        dt=1e-4,
        stiffness=12920.0,  # a contact of 0.01 s: 100 steps, so the integration keeps the energy
    )
    mass = 500 * 4 / 3 * np.pi * 0.05**3
    before = sim.kinetic_energy
    assert before == pytest.approx(mass * 1.0**2, rel=1e-6)  # two spheres, ½ m v² each
    sim.step(800)  # they meet after 0.05 s (500 steps) and part again
    assert sim.velocities[0, 0] < 0 < sim.velocities[1, 0], "they bounced"
    assert abs(sim.kinetic_energy / before - 1) < 1e-4
    assert sim.rotational_energy == 0


def test_spinning_spheres_carry_rotational_energy():
    sim = mochi.Simulation.from_arrays(
        np.array([[0.5, 0.5, 0.5]]),
        np.array([0.1]),
        angular_velocities=np.array([[0.0, 0.0, 3.0]]),
        backend="cpu",
        gravity=[0, 0, 0],
    )
    mass = 500 * 4 / 3 * np.pi * 0.1**3
    assert sim.rotational_energy == pytest.approx(0.5 * 0.4 * mass * 0.1**2 * 9.0, rel=1e-6)
    assert sim.kinetic_energy == 0


def test_the_walls_loads_and_the_flows_are_read_each_step():
    drum = mochi.Simulation("drum", spheres=200, backend="cpu")
    loads = drum.wall_loads
    assert [w["name"] for w in loads] == ["drum (generated)"]
    np.testing.assert_array_equal(loads[0]["force"], np.zeros(3))
    drum.step(1500)  # the grains have fallen onto the tube
    force = drum.wall_loads[0]["force"]
    assert force.shape == (3,) and force[2] < 0, force
    assert drum.flow == {
        "inserted": 0,
        "refused": 0,
        "removed": 0,
        "present": 200,
        "inserted_mass": 0.0,
        "removed_mass": 0.0,
    }
    hopper = mochi.Simulation("hopper", spheres=300, backend="cpu")
    assert [w["name"] for w in hopper.wall_loads] == ["hopper (generated)", "gate (generated)"]
    assert hopper.flow["present"] == len(hopper) == 300


def dem_backends():
    """Every DEM backend that runs here: cpu, and the wgpu ones where an adapter has them
    (lavapipe in CI, which must find wgpu-compute: a missing adapter fails there)."""
    available = {e["name"]: e for e in mochi.backends()}
    assert available["wgpu-compute"]["available"] or os.environ.get("CI") != "true", (
        f"CI expects wgpu-compute: {available['wgpu-compute']['reason']}"
    )
    return ["cpu"] + [b for b in ["wgpu-compute", "wgpu-rq", "optix"] if available[b]["available"]]


def lattice_keys():
    """A frictionless scene given whole (box, time step, stiffness): a run from arrays of the same
    spheres has the same step."""
    return dict(
        backend="cpu",
        box_lo=[0, 0, 0],
        box_hi=[0.3, 0.3, 0.3],
        contact="linear",
        dt=1e-4,
        stiffness=200.0,
    )


def lattice():
    at = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), -1).reshape(-1, 3)
    return 0.05 + 0.021 * at, np.full(len(at), 0.01)


@pytest.mark.parametrize("backend", dem_backends())
def test_state_set_between_steps_is_where_the_next_step_starts(backend):
    positions, radii = lattice()
    keys = {**lattice_keys(), "backend": backend}
    sim = mochi.Simulation.from_arrays(positions, radii, **keys)
    sim.step(1200)  # landing: the layers press on each other
    assert sim.contacts > 0
    v = sim.velocities.copy()
    v[:, 0] += 0.05
    sim.velocities = v
    np.testing.assert_array_equal(sim.velocities, v)
    moved = sim.positions + [0.0, 0.0, 0.001]
    sim.positions = moved
    np.testing.assert_allclose(sim.positions, moved, rtol=0, atol=1e-15)
    again = mochi.Simulation.from_arrays(sim.positions, sim.radii, velocities=v, **keys)
    sim.step(50)
    again.step(50)
    # The cpu step is bit for bit; a GPU's atomics add in any order.
    exact = backend == "cpu"
    np.testing.assert_allclose(sim.positions, again.positions, rtol=0, atol=0 if exact else 1e-9)
    np.testing.assert_allclose(sim.velocities, again.velocities, rtol=0, atol=0 if exact else 1e-6)


def test_gravity_set_between_steps_is_in_the_checkpoint(tmp_path):
    sim = mochi.Simulation("freefall", spheres=20, backend="cpu")
    sim.step(10)
    sim.gravity = [1.0, 0.0, -2.0]
    sim.checkpoint(tmp_path / "run.bin")
    again = mochi.Simulation.resume(tmp_path / "run.bin", backend="cpu")
    assert again.gravity == pytest.approx([1, 0, -2])
    sim.step(20)
    again.step(20)
    np.testing.assert_array_equal(sim.positions, again.positions)


def test_bad_state_is_refused_naming_it():
    positions, radii = lattice()
    sim = mochi.Simulation.from_arrays(positions, radii, **lattice_keys())
    before = sim.positions
    with pytest.raises(ValueError, match=r"velocities must have shape \(64, 3\), not \[3, 3\]"):
        sim.velocities = np.zeros((3, 3))
    bad = sim.positions.copy()
    bad[7, 1] = np.inf
    with pytest.raises(ValueError, match="sphere 7"):
        sim.positions = bad
    far = sim.positions.copy()
    far[3, 0] = 0.7  # the box is 0.3 wide: 0.4 past its wall
    with pytest.raises(ValueError, match="sphere 3: position .* outside the box"):
        sim.positions = far
    np.testing.assert_array_equal(sim.positions, before)  # nothing moved
    spin = np.zeros((64, 3))
    spin[0, 2] = 1.0
    sim.angular_velocities = spin  # the cpu step keeps any spin
    np.testing.assert_array_equal(sim.angular_velocities, spin.astype(np.float32))


def test_gravity_set_between_steps_acts_from_the_next_step():
    sim = mochi.Simulation.from_arrays(
        np.array([[0.5, 0.5, 0.5]]), np.array([0.01]), backend="cpu", box_lo=[0, 0, 0], box_hi=[1, 1, 1]
    )
    assert sim.gravity == pytest.approx([0, 0, -9.81])
    sim.step(10)
    v = sim.velocities[0].copy()
    sim.gravity = [2.0, 0.0, 0.0]
    assert sim.gravity == pytest.approx([2, 0, 0])
    sim.step(10)
    np.testing.assert_allclose(sim.velocities[0], v + [20 * sim.dt, 0, 0], rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match="single step"):
        sim.gravity = [0, 0, -1e12]
    assert sim.gravity == pytest.approx([2, 0, 0])  # refused: unchanged
    # Under a turning gravity it is gravity now, turning on from there.
    spun = mochi.Simulation("rotating", spheres=50, backend="cpu", contact="linear")
    spun.step(1000)
    spun.gravity = [0.0, 0.0, -1.0]
    assert spun.gravity == pytest.approx([0, 0, -1], abs=1e-6)


@pytest.mark.parametrize("backend", dem_backends())
def test_external_forces_and_torques_act_every_step_until_removed(backend):
    positions = np.array([[0.3, 0.5, 0.5], [0.7, 0.5, 0.5]])
    sim = mochi.Simulation.from_arrays(
        positions, np.array([0.01, 0.01]), backend=backend, box_lo=[0, 0, 0], box_hi=[1, 1, 1], gravity=[0, 0, 0]
    )
    np.testing.assert_array_equal(sim.external_forces, np.zeros((2, 3)))
    force = np.array([[1e-4, 0.0, -2e-4], [0.0, 3e-4, 0.0]])
    torque = np.array([[0.0, 0.0, 1e-9], [2e-9, 0.0, 0.0]])
    sim.external_forces = force
    sim.external_torques = torque
    np.testing.assert_array_equal(sim.external_forces, force.astype(np.float32))
    sim.step(10)
    mass = 500 * 4 / 3 * np.pi * 0.01**3
    inertia = 0.4 * mass * 0.01**2
    np.testing.assert_allclose(sim.velocities, 10 * sim.dt * force / mass, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(sim.angular_velocities, 10 * sim.dt * torque / inertia, rtol=1e-5, atol=1e-9)
    sim.external_forces = None  # removed; the torques stay
    np.testing.assert_array_equal(sim.external_forces, np.zeros((2, 3)))
    v = sim.velocities.copy()
    sim.step(10)
    np.testing.assert_array_equal(sim.velocities, v)
    np.testing.assert_allclose(sim.angular_velocities, 20 * sim.dt * torque / inertia, rtol=1e-5, atol=1e-9)
    with pytest.raises(ValueError, match=r"external_forces must have shape \(2, 3\)"):
        sim.external_forces = np.zeros((3, 3))
    with pytest.raises(ValueError, match="sphere 1"):
        sim.external_forces = np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    np.testing.assert_array_equal(sim.external_forces, np.zeros((2, 3)))  # refused: unchanged


def test_external_loads_are_refused_where_they_cannot_act():
    # The paper's frictionless step turns nothing.
    paper = mochi.Simulation("freefall", spheres=10, backend="cpu", contact="linear")
    with pytest.raises(ValueError, match="does not turn its spheres"):
        paper.external_torques = np.ones((10, 3))
    paper.external_forces = np.ones((10, 3))  # a force acts
    # Outflows change the spheres: a load per sphere cannot follow them.
    hopper = mochi.Simulation("hopper", spheres=50, backend="cpu")
    with pytest.raises(ValueError, match="inflows or outflows"):
        hopper.external_forces = np.ones((len(hopper), 3))


@pytest.mark.parametrize("backend", dem_backends())
def test_contact_forces_are_equal_and_opposite_and_sum_to_what_the_step_applies(backend):
    at = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3)
    positions = [0.1, 0.1, 0.0099] + 0.0199 * at  # pressed together, the bottom layer on the floor
    rng = np.random.default_rng(3)
    velocities = rng.uniform(-0.02, 0.02, size=(27, 3))
    sim = mochi.Simulation.from_arrays(
        positions, np.full(27, 0.01), velocities=velocities, backend=backend,
        box_lo=[0, 0, 0], box_hi=[0.3, 0.3, 0.3], dt=1e-5,
    )
    data = sim.contact_data()
    pairs, normal, tangential = data["pairs"], data["normal_force"], data["tangential_force"]
    assert pairs.dtype == np.int64 and pairs.shape == (len(data["overlap"]), 2)
    assert normal.shape == tangential.shape == (len(pairs), 3)
    spheres = pairs[:, 1] >= 0
    assert spheres.sum() >= 50 and np.all(pairs[spheres, 0] < pairs[spheres, 1])
    assert np.sum(pairs[:, 1] == -5) == 9  # the bottom layer on the floor (the low z wall)
    assert np.all(data["overlap"] > 0)
    assert np.abs(tangential).max() > 0, "friction acts"
    # Equal and opposite: the first partner takes +F, the second −F; the sums are the forces.
    total = normal + tangential
    sums = np.zeros((27, 3))
    np.add.at(sums, pairs[:, 0], total)
    np.add.at(sums, pairs[spheres, 1], -total[spheres])
    largest = np.abs(sim.forces).max()
    np.testing.assert_allclose(sums, sim.forces, rtol=0, atol=1e-5 * largest)
    assert sim.torques.shape == (27, 3) and np.abs(sim.torques).max() > 0
    # What the next step applies: m·Δv/dt − m·g.
    mass = 500 * 4 / 3 * np.pi * 0.01**3
    forces, v = sim.forces.copy(), sim.velocities.copy()
    sim.step(1)
    applied = mass * (sim.velocities - v) / sim.dt - mass * np.array(sim.gravity)
    np.testing.assert_allclose(applied, forces, rtol=0, atol=1e-3 * largest)


def test_material_keys_change_between_steps_and_the_rest_is_refused():
    # A sphere sliding on the floor: friction slows it; with friction off it keeps its speed.
    sim = mochi.Simulation.from_arrays(
        np.array([[0.1, 0.5, 0.0099]]), np.array([0.01]), velocities=np.array([[0.5, 0.0, 0.0]]),
        backend="cpu", box_lo=[0, 0, 0], box_hi=[1, 1, 1], dt=1e-5,
    )
    sim.step(200)
    assert sim.velocities[0, 0] < 0.49, "friction slows the sliding sphere"
    sim.change(friction=0.0, rolling_friction=0.0)
    v = sim.velocities[0, 0]
    sim.step(200)
    assert sim.velocities[0, 0] == pytest.approx(v, rel=1e-5), "without friction it slides on"
    # A time step the new law cannot keep stable is refused, and the run goes on as it was.
    with pytest.raises(ValueError, match="too large"):
        sim.change(young_modulus=1e13)
    with pytest.raises(ValueError, match=r"scene key domain.box_hi \(box_hi\): cannot change between steps"):
        sim.change({"box_hi": [2, 2, 2]})
    sim.step(10)
    assert sim.velocities[0, 0] == pytest.approx(v, rel=1e-5)
    # A smaller time step: the clock goes on from the time now, in steps of the new one.
    t = sim.time
    sim.change(dt=4e-6)
    assert sim.dt == pytest.approx(4e-6) and sim.step_count == round(t / 4e-6)
    assert abs(sim.time - t) <= 2e-6
    x = sim.positions[0, 0]
    sim.step(1000)
    assert sim.positions[0, 0] - x == pytest.approx(v * 4e-3, rel=1e-4)
    with pytest.raises(ValueError, match="too large"):
        sim.change(dt=1e-2)


def test_a_wall_turned_back_goes_on_from_where_it_is(tmp_path):
    plate = tmp_path / "plate.obj"
    plate.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    # A sphere resting on the floor, a plate above it coming down at 1 m/s.
    wall = {"mesh": str(plate), "translate": [0, 0, 0.03], "velocity": [0, 0, -1.0]}
    sim = mochi.Simulation.from_arrays(
        np.array([[0.5, 0.5, 0.01]]), np.array([0.01]), backend="cpu",
        box_lo=[0, 0, 0], box_hi=[1, 1, 1], gravity=[0, 0, 0], dt=1e-5, wall=wall,
    )
    sim.step(500)  # 5 mm down: the plate is 5 mm above the sphere's top
    sim.set_wall_motion(0, velocity=[0, 0, 0.0])
    sim.step(2000)
    np.testing.assert_array_equal(sim.wall_loads[0]["force"], np.zeros(3))  # held 5 mm above
    sim.set_wall_motion(0, velocity=[0, 0, -1.0])
    sim.step(600)  # 6 mm more: it presses 1 mm into the sphere
    assert sim.wall_loads[0]["force"][2] > 0, sim.wall_loads
    with pytest.raises(ValueError, match="the run has 1 mesh walls"):
        sim.set_wall_motion(3, velocity=[0, 0, 1.0])
    hopper = mochi.Simulation("hopper", spheres=50, backend="cpu")
    with pytest.raises(ValueError, match="moves as its scene says"):
        hopper.set_wall_motion(1, velocity=[1.0, 0, 0])


def test_a_mesh_wall_s_contacts_are_listed_with_its_negative_id(tmp_path):
    plate = tmp_path / "plate.obj"
    plate.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    # A sphere pressed 0.1 mm by a plate above it and 0.1 mm into the floor below.
    wall = {"mesh": str(plate), "translate": [0, 0, 0.0198]}
    sim = mochi.Simulation.from_arrays(
        np.array([[0.5, 0.5, 0.0099]]), np.array([0.01]), backend="cpu",
        box_lo=[0, 0, 0], box_hi=[1, 1, 1], gravity=[0, 0, 0], dt=1e-5, wall=wall,
    )
    data = sim.contact_data()
    assert sorted(data["pairs"][:, 1].tolist()) == [-7, -5]  # the mesh wall 0, the floor (low z)
    plate_row = list(data["pairs"][:, 1]).index(-7)
    normal = data["normal_force"][plate_row]
    assert normal[2] < 0 and abs(normal[0]) + abs(normal[1]) < 1e-6 * abs(normal[2])  # pushed down
    assert data["overlap"][plate_row] == pytest.approx(1e-4, rel=1e-3)
    np.testing.assert_allclose(sim.forces[0], data["normal_force"].sum(axis=0) + data["tangential_force"].sum(axis=0), rtol=1e-5)
    sim.step(1)
    # The plate takes the opposite of the force on the sphere.
    np.testing.assert_allclose(sim.wall_loads[0]["force"], -normal, rtol=1e-4)
