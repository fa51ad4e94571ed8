"""Scene files: TOML writer, round trips to the same model, units, and one located error per
kind of mistake (file, body and field named, a hint where the fix is obvious)."""

import math

import numpy as np
import pytest

import bfemp
from bfemp import scenefile
from bfemp.checkpoint import model_fingerprint
from bfemp.errors import SceneError
from bfemp.scenefile import tomllib  # the standard tomllib, or tomli on Python 3.10
from bfemp.scenefile._toml import dumps as dumps_toml
from geometry.mesh import TriMesh

NH = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
LE = bfemp.LinearElastic(E=2e5, nu=0.25, density=800.0)

BEAM = """
[scene]
dim = 2
gravity = [0.0, -9.81]

[simulation]
integrator = "newmark"
dt = "10 ms"
tol = 1e-6

[run]
t_end = 0.05
every = 2

[materials.rubber]
E = "5 MPa"
nu = 0.3
density = 1000.0

[[fem]]
name = "beam"
material = "rubber"
mesh = { shape = "rectangle", lower = [0.0, 0.0], upper = [1.0, 0.2], h = 0.1 }
prescribed = { type = "fixed" }
prescribed_nodes = { box = { lower = [-inf, -inf], upper = [1e-9, inf] } }
"""


def _equal(a, b):
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


def test_toml_writer_round_trips_nested_documents():
    doc = {
        "title": 'quote " backslash \\ tab \t newline \n unicode é ☃ \x01',
        "ints": [1, -2, 0],
        "floats": [0.1, -0.0, 1e-300, 1.5e300, math.inf, -math.inf, 100.0, 2.0 / 3.0],
        "nan": math.nan,
        "flag": False,
        "weird key": 1,
        "long": [[float(i), i / 7.0] for i in range(40)],
        "empty": [],
        "table": {"a": 1, "inline": {"x": [1, 2], "y": "z"}, "sub": {"deep": {"k": True}}},
        "items": [
            {"name": "a", "motion": {"type": "sequence", "segments": [{"d": 1.0}, {"d": 2.0}]}},
            {"name": "b", "parts": [{"p": 1}], "after": {"q": [0.5]}},
        ],
    }
    text = dumps_toml(doc, header_comment="a comment\nover two lines")
    assert text.startswith("# a comment\n# over two lines\n")
    assert _equal(tomllib.loads(text), doc)
    with pytest.raises(ValueError, match="mixed.*: a list mixing"):
        dumps_toml({"mixed": [1, {"a": 1}]})
    with pytest.raises(ValueError, match="null"):
        dumps_toml({"a": {"b": None}})


def _python_scene():
    """A scene from arrays and objects: everything must be written inline, exactly."""
    rng = np.random.default_rng(7)
    scene = bfemp.Scene(dim=2, gravity=(0.1, -9.81))
    ring = bfemp.shapes.ring((0.0, 0.0), 0.5, 0.8, h=0.2)
    v = rng.standard_normal((ring.n_points, 2))
    seq = bfemp.motion.Sequence(
        segments=(
            (0.1, bfemp.motion.Linear(velocity=(0.0, -1.0))),
            (math.inf, bfemp.motion.Rotation(center=(0.0, 0.0), angular_velocity=2.0)),
        )
    )
    scene.add_fem(ring, material=NH, velocity=v, prescribed=seq, prescribed_nodes=[3, 1, 4])
    plate = bfemp.shapes.rectangle((2.0, -1.0), (3.0, -0.8), h=0.1)
    idx = scene.add_fem(plate, material=LE, velocity=(1.0, 0.5), name="plate")
    scene.add_load(idx, rng.standard_normal((2, 2)), np.array([5, 2]))
    scene.add_load(idx, (0.0, -3.0))
    x, vol = bfemp.sample.box((4.0, 0.0), (4.5, 0.4), dx=0.1, ppc=4, jitter=0.5, rng=3)
    scene.add_mpm(x, vol * (1.0 + 0.1 * rng.random(vol.size)), material=LE, name="blob")
    scene.set_grid(dx=0.1, origin=(0.013, -0.02))
    scene.set_contact(dhat=1e-3, kappa="auto", mu=0.2, eps_v=1e-4, friction_iterations=5)
    box = bfemp.levelset.Box(lower=(-1.0, -5.0), upper=(9.0, 5.0))
    floor = bfemp.levelset.HalfPlane(point=(0.0, -2.0), normal=(0.0, 1.0))
    lift = bfemp.motion.Linear(velocity=(0.0, 0.1))
    scene.add_boundary(floor, "slip", motion=lift)
    scene.add_boundary(bfemp.levelset.Inverted(box), kind="sticky")
    disk = bfemp.levelset.Disk(center=(6.0, 0.0), radius=0.3)
    scene.add_boundary(bfemp.levelset.Union(disk, box), kind="separate")
    return scene


def test_scene_written_from_python_reads_back_to_the_same_model(tmp_path):
    scene = _python_scene()
    text = scenefile.save(
        scene, tmp_path / "scene.toml", simulation={"dt": 1e-3}, run={"t_end": 1.0}
    )
    assert (tmp_path / "scene.toml").read_text() == text
    again = scenefile.read_scene(tmp_path / "scene.toml")
    a, b = scene.build(), again.build()
    assert model_fingerprint(a) == model_fingerprint(b)
    assert np.array_equal(a.fem_load, b.fem_load) and np.array_equal(a.mpm_X, b.mpm_X)
    assert b.fem_bodies[0].prescribed_motion == a.fem_bodies[0].prescribed_motion
    # from text too, and the settings come back
    sf = scenefile.loads(text)
    assert sf.simulation == {"dt": 1e-3} and sf.run == {"t_end": 1.0}
    assert model_fingerprint(sf.scene.build()) == model_fingerprint(a)


def test_3d_scene_round_trip():
    scene = bfemp.Scene(dim=3, gravity=(0.0, 0.0, -9.81))
    box = bfemp.shapes.box((0.0, 0.0, 0.0), (1.0, 0.5, 0.5), h=0.25)
    rot = bfemp.motion.Rotation(center=(0.5, 0.0, 0.0), angular_velocity=1.0, axis=(1, 1, 0))
    scene.add_fem(box, material=NH, prescribed=rot, prescribed_nodes=box.points[:, 0] < 1e-9)
    x, vol = bfemp.sample.box((2.0, 0.0, 0.0), (2.4, 0.4, 0.4), dx=0.2, ppc=8)
    scene.add_mpm(x, vol, material=NH, velocity=(0.0, 0.0, -1.0))
    scene.set_grid(dx=0.2)
    again = scenefile.read_scene(scenefile.save(scene))
    a, b = scene.build(), again.build()
    # every array bitwise; the rotation axis is stored normalised, and normalising the written
    # unit vector again may move it by an ulp: (1, 1, 0) / sqrt(2) is such a case.
    # (scripted nodes start with the rotation's velocity, so fem_v0 moves by round-off too)
    arrays_a, arrays_b = _arrays(a), _arrays(b)
    assert np.allclose(arrays_a.pop("fem_v0"), arrays_b.pop("fem_v0"), rtol=1e-15, atol=0)
    assert all(np.array_equal(arrays_a[k], arrays_b[k]) for k in arrays_a)
    axis_a = a.fem_bodies[0].prescribed_motion.axis
    axis_b = b.fem_bodies[0].prescribed_motion.axis
    assert np.allclose(axis_a, axis_b, rtol=0, atol=2e-16) and axis_a != axis_b
    rot = bfemp.motion.Rotation(center=(0.5, 0.0, 0.0), angular_velocity=1.0, axis=(1, 2, 3))
    scene._fem[0] = scene._fem[0].__class__(**{**scene._fem[0].__dict__, "motion": rot})
    again = scenefile.read_scene(scenefile.save(scene))
    assert model_fingerprint(again.build()) == model_fingerprint(scene.build())


def _arrays(model):
    return {k: v for k, v in vars(model).items() if isinstance(v, np.ndarray)}


def test_scene_file_sources_are_written_back_as_described(tmp_path):
    box = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 1.0), h=0.5)
    box.write(tmp_path / "plate.vtu")
    text = (
        BEAM
        + """
[[fem]]
name = "plate"
material = { type = "linear_elastic", E = 1e6, nu = 0.2, density = 500.0 }
mesh = { file = "plate.vtu" }

[grid]
dx = 0.1

[[mpm]]
name = "blob"
material = "rubber"

[mpm.particles]
sample = "levelset"
levelset = { type = "disk", center = [3.0, 3.0], radius = 0.3 }
lower = [2.5, 2.5]
upper = [3.5, 3.5]
ppc = 4
"""
    )
    (tmp_path / "scene.toml").write_text(text)
    sf = scenefile.load(tmp_path / "scene.toml")
    written = scenefile.save(sf.scene)
    doc = tomllib.loads(written)
    assert doc["fem"][0]["mesh"]["shape"] == "rectangle"
    assert doc["fem"][0]["prescribed_nodes"]["box"]["upper"][0] == 1e-9
    assert doc["fem"][0]["material"] == "rubber"
    assert doc["fem"][1]["mesh"] == {"file": str((tmp_path / "plate.vtu").resolve())}
    assert doc["mpm"][0]["particles"]["sample"] == "levelset"
    again = scenefile.loads(written)
    assert model_fingerprint(again.scene.build()) == model_fingerprint(sf.scene.build())


def test_cantilever_example_is_the_demo_scene():
    from bfemp.demo import cantilever_scene

    sf = scenefile.load("examples/cantilever.toml")
    assert model_fingerprint(sf.scene.build()) == model_fingerprint(cantilever_scene().build())
    assert sf.simulation["integrator"] == "newmark" and sf.simulation["dt"] == 0.01


def test_rings_example_is_the_demo_scene():
    from bfemp.demo import colliding_rings_scene

    sf = scenefile.load("examples/rings.toml")
    assert model_fingerprint(sf.scene.build()) == model_fingerprint(colliding_rings_scene().build())
    assert sf.simulation["integrator"] == "newmark_implicit_contact"
    assert sf.simulation["dt"] == 2e-3


def test_units_are_converted_and_settings_read():
    sf = scenefile.loads(BEAM)
    assert sf.simulation == {"integrator": "newmark", "dt": 0.01, "tol": 1e-6}
    assert sf.scene._fem[0].material.E == 5e6
    assert sf.run_settings() == {"t_end": 0.05, "every": 2, "checkpoint_every": 0}
    assert sf.run_settings(t_end=0.2)["t_end"] == 0.2
    sim = bfemp.Simulation.from_file(sf)
    assert sim.dt == 0.01 and sim.integrator.name == "newmark"
    clamped = sim.model.fem_prescribed
    assert np.array_equal(clamped, sim.model.fem_X[:, 0] <= 1e-9)


def _replace(old, new, text=BEAM):
    assert old in text
    return text.replace(old, new)


BAD = [
    # (scene text, fragments the message must hold)
    (_replace("[simulation]", "[simulaton]"), ["unknown key 'simulaton'", "simulation"]),
    (_replace("density = 1000.0", "densty = 1000.0"), ["materials.rubber", "'densty'", "density"]),
    (_replace('dt = "10 ms"', 'dt = "abc"'), ["simulation.dt", "must be a time in s"]),
    (_replace('dt = "10 ms"', 'dt = "10 m"'), ["simulation.dt", "'m' is a length"]),
    (_replace('dt = "10 ms"', "dt = 0"), ["simulation.dt", "must be > 0 s"]),
    (_replace('dt = "10 ms"', "dt = -1e-3"), ["simulation.dt", "> 0"]),
    (_replace('dt = "10 ms"', "dt = nan"), ["simulation.dt", "finite"]),
    (_replace('dt = "10 ms"', "dt = true"), ["simulation.dt", "boolean"]),
    (_replace('E = "5 MPa"', "E = 0"), ["materials.rubber.E", "> 0 Pa", "Young"]),
    (_replace('E = "5 MPa"', "E = -5e6"), ["materials.rubber.E", "> 0"]),
    (_replace('E = "5 MPa"', 'E = "5 kg/m^3"'), ["materials.rubber.E", "is a density"]),
    (_replace("nu = 0.3", "nu = 0.5"), ["materials.rubber.nu", "< 0.5", "incompressible"]),
    (_replace("density = 1000.0", "density = 0.0"), ["materials.rubber.density", "> 0"]),
    (_replace("h = 0.1", "h = 0.0"), ["fem body 'beam'", "mesh.h", "> 0"]),
    (_replace('shape = "rectangle"', 'shape = "rectngle"'), ["mesh.shape", "rectangle"]),
    (_replace("h = 0.1 }", "h = 0.1, radius = 2 }"), ["fem body 'beam'", "'radius'"]),
    (_replace('material = "rubber"', 'material = "steel"'), ["'beam'", "material", "'steel'"]),
    (_replace('name = "beam"\n', 'name = "beam"\nvelocity = [1.0]\n'), ["velocity", "2 numbers"]),
    (
        _replace("upper = [1e-9, inf]", "upper = [-1.0, inf]"),
        ["fem body 'beam'", "prescribed_nodes", "selects no node"],
    ),
    (_replace('{ type = "fixed" }', '{ type = "fixd" }'), ["prescribed.type", "'fixed'"]),
    (_replace("dim = 2", "dim = 4"), ["scene.dim", "2 or 3"]),
    (_replace("[scene]", "[scene"), ["not valid TOML"]),
    (BEAM + "\n[grid]\ndx = 0.0\n", ["grid.dx", "> 0"]),
    (BEAM + "\n[grid]\ndx = -1.0\n", ["grid.dx", "> 0"]),
    (BEAM + "\n[contact]\ndhat = 0.0\n", ["contact.dhat", "> 0"]),
    (BEAM + "\n[contact]\nkappa = 1e5\n", ["contact", "missing key 'dhat'"]),
    (BEAM + '\n[[load]]\nbody = "bean"\nforce = [0.0, 1.0]\n', ["load[0].body", "'beam'"]),
    (
        BEAM + '\n[[mpm]]\nname = "blob"\nmaterial = "rubber"\n'
        'particles = { sample = "box", lower = [3, 0], upper = [4, 1], ppc = 4 }\n',
        ["mpm body 'blob'", "particles.dx", "[grid]"],
    ),
    (
        BEAM + '\n[[mpm]]\nname = "blob"\nmaterial = "rubber"\n'
        "particles = [[3.0, 0.0], [3.0, nan]]\nvolumes = [0.1, 0.1]\n",
        ["mpm body 'blob'", "particles", "NaN"],
    ),
    (
        BEAM + '\n[[mpm]]\nname = "blob"\nmaterial = "rubber"\n'
        "particles = [[3.0, 0.0], [3.0, 1.0]]\nvolumes = [0.1, -0.1]\n",
        ["mpm body 'blob'", "volumes", "positive"],
    ),
]


@pytest.mark.parametrize("text, fragments", BAD)
def test_each_mistake_names_file_body_and_field(text, fragments):
    with pytest.raises(SceneError) as info:
        scenefile.loads(text, file="bad.toml")
    message = str(info.value)
    assert message.startswith("bad.toml: "), message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def _mesh_scene(points, cells):
    return _replace(
        'mesh = { shape = "rectangle", lower = [0.0, 0.0], upper = [1.0, 0.2], h = 0.1 }',
        f"mesh = {{ points = {points}, cells = {cells} }}",
    ).replace("prescribed_nodes = { box = { lower = [-inf, -inf], upper = [1e-9, inf] } }", "")


@pytest.mark.parametrize(
    "points, cells, fragments",
    [
        ("[[0, 0], [1, 0], [0, 1], [1, 1]]", "[[0, 1, 2], [1, 2, 3]]", ["inverted", "[1]", "flip"]),
        ("[[0, 0], [1, 0], [2, 0], [1, 1]]", "[[0, 1, 2], [0, 1, 3]]", ["degenerate", "[0]"]),
        ("[[0, 0], [1, 0], [0, nan]]", "[[0, 1, 2]]", ["mesh.points", "NaN"]),
        ("[[0, 0], [1, 0], [0, 1]]", "[[0, 1, 5]]", ["mesh", "outside [0, 3)"]),
        ("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "[[0, 1, 2]]", ["mesh.points", "rows of 2"]),
    ],
)
def test_bad_meshes_are_located(points, cells, fragments):
    with pytest.raises(SceneError) as info:
        scenefile.loads(_mesh_scene(points, cells), file="m.toml")
    message = str(info.value)
    assert message.startswith("m.toml: fem body 'beam': mesh"), message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_missing_files_are_named(tmp_path):
    text = _replace(
        'mesh = { shape = "rectangle", lower = [0.0, 0.0], upper = [1.0, 0.2], h = 0.1 }',
        'mesh = { file = "nowhere.msh" }',
    )
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(SceneError, match=r"s.toml: fem body 'beam': mesh.file: .*nowhere.msh"):
        scenefile.load(tmp_path / "s.toml")
    with pytest.raises(SceneError, match="scene file not found"):
        scenefile.load(tmp_path / "missing.toml")


def test_missing_settings_are_named():
    sf = scenefile.loads(_replace("t_end = 0.05", "").replace('dt = "10 ms"', ""), file="x.toml")
    with pytest.raises(SceneError, match=r"x.toml: run.t_end: missing.*--t-end"):
        sf.run_settings()
    with pytest.raises(SceneError, match=r"x.toml: simulation.dt: missing"):
        bfemp.Simulation.from_file(sf)


@pytest.mark.parametrize(
    "call, fragment",
    [
        (lambda: bfemp.NeoHookean(E=1e6, nu=0.5, density=1.0), "nu"),
        (lambda: bfemp.NeoHookean(E=-1.0, nu=0.3, density=1.0), "E"),
        (lambda: bfemp.LinearElastic(E=1.0, nu=0.3, density=0.0), "density"),
        (lambda: bfemp.Scene(dim=2).set_grid(dx=0.0), "dx"),
        (lambda: bfemp.Scene(dim=2).set_contact(dhat=-1.0), "dhat"),
        (lambda: bfemp.Simulation(scenefile.loads(BEAM).scene, dt=0.0), "dt"),
        (lambda: bfemp.Simulation(scenefile.loads(BEAM).scene, dt=math.nan), "dt"),
    ],
)
def test_api_mistakes_name_the_argument(call, fragment):
    with pytest.raises(ValueError, match=fragment):
        call()


# --------------------------------------------------------------------------- issue 12 (inputs)
def _plate_file_with_unused_point(path):
    """A 1 x 0.2 plate written with meshio, point 0 used by no cell; the file indices of the
    nodes on x = 0 and on x = 1."""
    import meshio

    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.2), h=0.1)
    pts = np.vstack([[0.5, 0.5], mesh.points])
    meshio.write(
        path, meshio.Mesh(np.hstack([pts, np.zeros((len(pts), 1))]), [("triangle", mesh.cells + 1)])
    )
    left = 1 + np.flatnonzero(mesh.points[:, 0] < 1e-9)
    right = 1 + np.flatnonzero(mesh.points[:, 0] > 1.0 - 1e-9)
    return left, right


def _file_scene(nodes, load_nodes):
    return (
        _replace(
            'mesh = { shape = "rectangle", lower = [0.0, 0.0], upper = [1.0, 0.2], h = 0.1 }',
            'mesh = { file = "plate.vtu" }',
        ).replace(
            "prescribed_nodes = { box = { lower = [-inf, -inf], upper = [1e-9, inf] } }",
            f"prescribed_nodes = {nodes}",
        )
        + f'\n[[load]]\nbody = "beam"\nforce = [0.0, -1.0]\nnodes = {load_nodes}\n'
    )


def test_node_indices_of_a_mesh_file_with_an_unused_point_use_the_file_numbering(tmp_path):
    left, right = _plate_file_with_unused_point(tmp_path / "plate.vtu")
    path = tmp_path / "scene.toml"
    path.write_text(_file_scene(left.tolist(), right.tolist()))
    model = scenefile.load(path).scene.build()
    np.testing.assert_array_equal(model.fem_prescribed, model.fem_X[:, 0] < 1e-9)
    np.testing.assert_array_equal(model.fem_load[:, 1] < 0, model.fem_X[:, 0] > 1.0 - 1e-9)
    # written back (the mesh as the file, indices in its numbering) to the same model
    again = scenefile.loads(scenefile.save(scenefile.load(path).scene))
    assert model_fingerprint(again.scene.build()) == model_fingerprint(model)
    assert np.array_equal(again.scene.build().fem_load, model.fem_load)


def test_node_indices_of_a_pruned_point_are_refused_naming_index_and_file(tmp_path):
    left, right = _plate_file_with_unused_point(tmp_path / "plate.vtu")
    path = tmp_path / "scene.toml"
    for nodes, load, field in (
        ([0, *left], right, "prescribed_nodes"),
        (left, [0], "load[0].nodes"),
    ):
        path.write_text(_file_scene(list(map(int, nodes)), list(map(int, load))))
        with pytest.raises(SceneError) as info:
            scenefile.load(path)
        message = str(info.value)
        assert field in message and "[0] in the numbering of" in message, message
        assert "plate.vtu" in message and "no cell uses" in message


def test_a_clockwise_mesh_file_is_accepted(tmp_path):
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.2), h=0.1)
    TriMesh(mesh.points, mesh.cells[:, [0, 2, 1]]).write(tmp_path / "plate.vtu")
    text = _replace(
        'mesh = { shape = "rectangle", lower = [0.0, 0.0], upper = [1.0, 0.2], h = 0.1 }',
        'mesh = { file = "plate.vtu" }',
    )
    (tmp_path / "scene.toml").write_text(text)
    model = scenefile.load(tmp_path / "scene.toml").scene.build()
    assert np.all(model.fem_cell_volume > 0)
    assert model_fingerprint(model) == model_fingerprint(scenefile.loads(BEAM).scene.build())


def test_a_rigid_plate_of_slivers_loads_and_a_deformable_one_names_the_aspect_ratio():
    points, cells = "[[0, 0], [40, 0], [40, 0.01], [0, 0.01]]", "[[0, 1, 2], [0, 2, 3]]"
    rigid = _mesh_scene(points, cells)  # prescribed = fixed, every node
    np.testing.assert_allclose(scenefile.loads(rigid).scene.build().fem_cell_volume, [0.2, 0.2])
    free = rigid.replace('prescribed = { type = "fixed" }', "")
    with pytest.raises(SceneError) as info:
        scenefile.loads(free, file="m.toml")
    message = str(info.value)
    assert message.startswith("m.toml: fem body 'beam': mesh: ") and "aspect ratio up to" in message
    assert "indices [0, 1]" in message and "re-mesh" in message


@pytest.mark.parametrize(
    "text, fragments",
    [
        (BEAM + '\n[contact]\ndhat = 1e-3\nkappa = "automatic"\n', ["contact.kappa", '"auto"']),
        (
            _replace(
                "prescribed_nodes = { box = { lower = [-inf, -inf], upper = [1e-9, inf] } }",
                "prescribed_nodes = []",
            ),
            ["prescribed_nodes", "selects no node"],
        ),
        (
            BEAM + '\n[grid]\ndx = 0.1\n[[mpm]]\nname = "blob"\nmaterial = "rubber"\n'
            "particles = [[3.0, 0.0], [3.0, 1.0]]\nvolumes = [0.01, 0.01]\n"
            '[[load]]\nbody = "blob"\nforce = [0.0, 1.0]\n',
            ["load[0].body", "FEM bodies only", "'blob' is an MPM body"],
        ),
    ],
)
def test_unclear_scene_file_inputs_name_the_allowed_values(text, fragments):
    with pytest.raises(SceneError) as info:
        scenefile.loads(text, file="bad.toml")
    for fragment in fragments:
        assert fragment in str(info.value), (fragment, str(info.value))


def test_the_rotation_axis_is_not_checked_in_2d():
    text = _replace(
        '{ type = "fixed" }',
        '{ type = "rotation", center = [0, 0], angular_velocity = 1.0, axis = [0, 0, 0] }',
    )
    motion = scenefile.loads(text).scene.build().fem_bodies[0].prescribed_motion
    assert motion.axis == (0.0, 0.0, 1.0)
