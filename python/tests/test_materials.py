"""Several materials through mochi.Simulation on the cpu backend: the scene dict's `material`,
`material_pair`, `box_material` and the walls' and inflows' `material` give the run of the scene
file, each sphere's material comes back (input order, read-only, in frames and checkpoints), and
a material name or index the scene lacks is one clear ValueError."""

import numpy as np
import pytest

import mochi

GLASS = {"name": "glass", "density": 2500, "restitution": 0.9, "friction": 0.3}
STEEL = {"name": "steel", "density": 7800, "young_modulus": 3e5, "restitution": 0.5}
PAIR = {"materials": ["glass", "steel"], "friction": 0.2}
INFLOW = {
    "lo": [0.05, 0.05, 0.2],
    "hi": [0.25, 0.25, 0.28],
    "rate": 200,
    "sphere_radius": 0.008,
    "material": "steel",
}

SCENE_TOML = """scene = "input"
input = "heap.csv"
young_modulus = 1e5
box_lo = [0, 0, 0]
box_hi = [0.3, 0.3, 0.3]
box_material = "steel"
[[material]]
name = "glass"
density = 2500
restitution = 0.9
friction = 0.3
[[material]]
name = "steel"
density = 7800
young_modulus = 3e5
restitution = 0.5
[[material_pair]]
materials = ["glass", "steel"]
friction = 0.2
[[inflow]]
lo = [0.05, 0.05, 0.2]
hi = [0.25, 0.25, 0.28]
rate = 200
sphere_radius = 0.008
material = "steel"
[[wall]]
mesh = "square.obj"
translate = [0, 0, 0.15]
scale = 0.3
material = "glass"
"""


def heap(tmp_path, materials=None):
    """27 spheres of radius 1 cm thrown onto the floor, every third glass (0), the others steel
    (1), by the CSV's `material` column (or `materials`); the file and the materials."""
    k = np.arange(27)
    at = 0.0101 + 0.0199 * np.stack([k % 3, (k // 3) % 3, k // 9], axis=1)
    if materials is None:
        materials = (k % 3 != 0).astype(np.uint8)
    rows = [
        f"{x},{y},{z},0.01,{0.1 * (i % 3 - 1)},-0.05,-0.1,{m}"
        for i, ((x, y, z), m) in enumerate(zip(at, materials))
    ]
    path = tmp_path / "heap.csv"
    path.write_text("x,y,z,r,vx,vy,vz,material\n" + "\n".join(rows) + "\n")
    return path, np.asarray(materials, np.uint8)


def square(tmp_path):
    """A unit square (two triangles) for a mesh wall: scaled and raised, a shelf in the box."""
    mesh = tmp_path / "square.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    return mesh


def two_materials(tmp_path, **changes):
    """The scene of SCENE_TOML as a dict (lone dicts for the one-table arrays), with `changes`."""
    path, _ = heap(tmp_path)
    scene = {
        "scene": "input",
        "input": path,
        "young_modulus": 1e5,
        "box_lo": [0, 0, 0],
        "box_hi": [0.3, 0.3, 0.3],
        "box_material": "steel",
        "material": [GLASS, STEEL],
        "material_pair": PAIR,
        "inflow": INFLOW,
        "wall": {"mesh": square(tmp_path), "translate": [0, 0, 0.15], "scale": 0.3,
                 "material": "glass"},
    }
    return scene | changes


def test_a_two_material_scene_from_a_dict_runs_as_its_scene_file(tmp_path):
    _, materials = heap(tmp_path)
    sim = mochi.Simulation(two_materials(tmp_path), backend="cpu")
    assert sim.material_names == ["glass", "steel"]
    np.testing.assert_array_equal(sim.materials, materials)
    sim.step(120)
    n = len(sim)
    assert n > 27, "the inflow inserted no sphere"
    # The file's spheres keep theirs, in input order; the inflow's are steel.
    got = sim.materials
    assert got.dtype == np.uint8 and got.shape == (n,) and not got.flags.writeable
    np.testing.assert_array_equal(got[:27], materials)
    assert (got[27:] == 1).all()
    with pytest.raises(ValueError, match="read-only"):
        got[0] = 1
    # The scene file gives the same run.
    (tmp_path / "scene.toml").write_text(SCENE_TOML)
    from_file = mochi.Simulation(tmp_path / "scene.toml", backend="cpu")
    from_file.step(120)
    for name in ["positions", "velocities", "angular_velocities", "materials"]:
        np.testing.assert_array_equal(getattr(from_file, name), getattr(sim, name), name)
    # Frames carry the materials.
    for ext in ["vtu", "csv", "npy"]:
        path = tmp_path / f"frame.{ext}"
        sim.write_frame(path)
        np.testing.assert_array_equal(mochi.read_frame(path)["materials"], got, ext)


def test_a_two_material_run_resumes_bit_for_bit(tmp_path):
    scene = two_materials(tmp_path)
    straight = mochi.Simulation(scene, backend="cpu")
    straight.step(100)
    first = mochi.Simulation(scene, backend="cpu")
    first.step(40)
    first.checkpoint(tmp_path / "run.bin")
    resumed = mochi.Simulation.resume(tmp_path / "run.bin", backend="cpu")
    assert resumed.material_names == ["glass", "steel"]
    resumed.step(60)
    for name in ["positions", "velocities", "angular_velocities", "radii", "materials"]:
        np.testing.assert_array_equal(getattr(resumed, name), getattr(straight, name), name)


def test_a_scene_of_one_material_has_every_sphere_of_it():
    sim = mochi.Simulation({"scene": "freefall", "spheres": 20}, backend="cpu")
    assert sim.material_names == ["default"]
    np.testing.assert_array_equal(sim.materials, np.zeros(20, np.uint8))


def test_a_dict_of_the_material_table_sets_its_keys_and_a_named_one_is_a_material():
    sim = mochi.Simulation(
        {"source": {"scene": "freefall", "spheres": 20}, "material": {"friction": 0.2}},
        backend="cpu",
    )
    assert sim.material_names == ["default"]
    # The table's keys are the one material's: one of the other law is refused.
    with pytest.raises(ValueError, match="young_modulus.*hertz-mindlin"):
        mochi.Simulation(
            {"scene": "freefall", "spheres": 20, "material": {"contact": "linear", "young_modulus": 1e9}},
            backend="cpu",
        )
    # A lone dict with a name is one [[materials]] table.
    sim = mochi.Simulation({"scene": "freefall", "spheres": 20, "material": GLASS}, backend="cpu")
    assert sim.material_names == ["glass"]


NOT_A_TABLE = (
    r': names material "nope", which is not one of the \[\[materials\]\] tables '
    r'\("glass", "steel"\)'
)


@pytest.mark.parametrize(
    "change, words",
    [
        ({"box_material": "nope"}, "box_material" + NOT_A_TABLE),
        ({"inflow": INFLOW | {"material": "nope"}}, "inflow.material" + NOT_A_TABLE),
        ({"material_pair": {"materials": ["glass", "nope"]}}, "material_pairs.materials" + NOT_A_TABLE),
        ({"material": [GLASS, STEEL, STEEL]}, 'the material name "steel" is given twice'),
        ({"material": [GLASS | {"hardness": 3}, STEEL]}, "unknown field `hardness`"),
        ({"material": [GLASS, STEEL | {"restitution": 0}]}, 'material "steel": .*restitution'),
    ],
    ids=["box", "inflow", "pair", "twice", "unknown key", "bad value"],
)
def test_a_bad_material_is_one_clear_value_error(tmp_path, change, words):
    with pytest.raises(ValueError, match=words):
        mochi.Simulation(two_materials(tmp_path, **change), backend="cpu")


def test_a_wall_of_a_material_the_scene_lacks_is_refused(tmp_path):
    wall = {"mesh": square(tmp_path), "material": "nope"}
    with pytest.raises(ValueError, match="wall.material" + NOT_A_TABLE):
        mochi.Simulation(two_materials(tmp_path, wall=wall), backend="cpu")


def test_a_sphere_of_a_material_the_scene_lacks_is_refused_naming_the_file(tmp_path):
    path, _ = heap(tmp_path, materials=[0] * 26 + [2])
    scene = {"scene": "input", "input": path, "material": [GLASS, STEEL]}
    with pytest.raises(ValueError, match="heap.csv: sphere 26: material 2, but the scene has 2"):
        mochi.Simulation(scene, backend="cpu")
    path, _ = heap(tmp_path)
    with pytest.raises(ValueError, match=r"heap.csv: sphere 1: material 1, but the scene has 1 material \("):
        mochi.Simulation({"scene": "input", "input": path}, backend="cpu")
