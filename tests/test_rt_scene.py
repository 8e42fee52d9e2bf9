"""The shared ray-tracing scene: scene files, walls, in-place body updates, ray casts, clearance."""
import numpy as np
import pytest

from rtchannel.scene.rt_scene import SCENES, RadarPlacementError, RTScene, get_scene
from rtchannel.scene.skin import SkinMaterial, gabriel_dry_skin


def _box_mesh(centre, half):
    """Closed axis-aligned box [8 vertices, 12 outward triangles]."""
    c, h = np.asarray(centre, float), np.asarray(half, float)
    v = c + h * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


@pytest.fixture(scope="module")
def room():
    return get_scene("room", "2k", 1.75, 24.125e9)


def test_skin_default_is_gabriel_dry_skin():
    eps, sig = gabriel_dry_skin(24.125e9)
    # Gabriel 1996 dry skin near 24 GHz: eps' ~ 19, sigma ~ 23 S/m (dominated by the 7.2 ps water pole);
    # 5 % bands catch a wrong pole or unit without restating the formula.
    assert abs(eps - 18.9) < 0.05 * 18.9 and abs(sig - 22.9) < 0.05 * 22.9
    assert SkinMaterial().relative_permittivity == pytest.approx(eps)
    with pytest.raises(ValueError, match="scattering pattern"):
        SkinMaterial(scattering_pattern="mirror")


def test_room_walls(room):
    walls = {w.name: w for w in room.walls}
    assert set(walls) == {"floor", "wall_xp", "wall_xn", "wall_yp", "wall_yn"}
    expect = {"floor": ((0, 0, 0), (0, 0, 1)), "wall_xp": ((4, 0, 1.5), (-1, 0, 0)),
              "wall_xn": ((-4, 0, 1.5), (1, 0, 0)), "wall_yp": ((0, 4, 1.5), (0, -1, 0)),
              "wall_yn": ((0, -4, 1.5), (0, 1, 0))}
    for name, (p, n) in expect.items():
        w = walls[name]
        # float32 scene geometry: 1e-5 m / 1e-6 is far below any physical effect and above rounding.
        np.testing.assert_allclose(w.point, p, atol=1e-5)
        np.testing.assert_allclose(w.normal, n, atol=1e-6)
        assert w.area == pytest.approx(64.0 if name == "floor" else 24.0, rel=1e-5)
        # ITU-R P.2040 concrete: eps' = 5.24, sigma = 0.0462 f_GHz^0.7822 S/m.
        sigma = 0.0462 * 24.125 ** 0.7822
        assert w.relative_permittivity.real == pytest.approx(5.24, rel=1e-5)
        assert -w.relative_permittivity.imag == pytest.approx(sigma / (2 * np.pi * 24.125e9 * 8.8541878e-12), rel=1e-3)


def test_free_space_has_only_the_body():
    sc = get_scene("free_space", "2k", 1.75, 24.125e9)
    assert sc.walls == [] and list(sc.sionna_scene.objects) == ["body"]
    r = sc.cast(np.array([[3.0, 0, 1.1], [3.0, 0, 1.1]]), np.array([[-1.0, 0, 0], [1.0, 0, 0]]))
    assert r["hit"].tolist() == [True, False] and r["body"].tolist() == [True, False]
    assert r["t"][1] == np.inf and r["prim"][1] == -1


def test_set_body_moves_geometry(room):
    rest = room.body_vertices.copy()
    o, d = np.array([[3.0, 0.0, 1.1]]), np.array([[-1.0, 0.0, 0.0]])
    t0 = room.cast(o, d)
    assert t0["body"][0]
    room.set_body(rest + [0.5, 0.0, 0.0])
    t1 = room.cast(o, d)
    room.set_body(rest)
    # The same triangle is hit 0.5 m earlier; float32 ray tracing at ~3 m is good to ~1 um.
    assert t1["body"][0] and t1["prim"][0] == t0["prim"][0]
    assert t0["t"][0] - t1["t"][0] == pytest.approx(0.5, abs=1e-5)
    assert room.cast(o, d)["t"][0] == pytest.approx(t0["t"][0], abs=1e-6)
    with pytest.raises(ValueError, match="shape"):
        room.set_body(rest[:10])


def test_clearance(room):
    room.check_clearance(np.array([[3.0, 0.0, 1.1], [0.0, -3.0, 1.1]]))
    with pytest.raises(RadarPlacementError, match=r"0\.50 cm from 'wall_xp'"):
        room.check_clearance(np.array([[3.995, 0.0, 1.1]]))
    top = room.body_vertices[np.argmax(room.body_vertices[:, 2])]
    with pytest.raises(RadarPlacementError, match="'body'"):
        room.check_clearance(top + [0, 0, 0.004])


def test_user_scene_with_box(tmp_path):
    xml = SCENES["room"].read_text().replace(
        "</scene>", '<shape type="cube" id="table"><transform name="to_world"><scale value="0.5"/>'
                    '<translate x="-2" y="1" z="0.5"/></transform><ref id="concrete" name="bsdf"/></shape></scene>')
    path = tmp_path / "furnished.xml"
    path.write_text(xml)
    v, f = _box_mesh((0, 0, 1), (0.2, 0.2, 0.2))
    sc = RTScene(path, f, v, 24.125e9)
    # The bottom face lies on the floor plane, so it is oriented like the floor (+z) too.
    tops = [w for w in sc.walls if w.name.startswith("table") and w.normal[2] > 0.99 and w.point[2] > 0.5]
    assert len(tops) == 1 and tops[0].point[2] == pytest.approx(1.0, abs=1e-5)
    assert tops[0].area == pytest.approx(1.0, rel=1e-5)
    assert len([w for w in sc.walls if w.name.startswith("table")]) == 6  # bottom face too (it is 1 m^2)
    hit = sc.cast(np.array([[-2.0, 1.0, 2.5]]), np.array([[0.0, 0.0, -1.0]]))
    assert hit["hit"][0] and not hit["body"][0] and hit["t"][0] == pytest.approx(1.5, abs=1e-5)
    with pytest.raises(ValueError, match="neither"):
        RTScene(tmp_path / "missing.xml", f, v, 24.125e9)


# --- scene-file sandbox (issue 13): no file outside the scene's folder is read, errors never echo content
import shutil  # noqa: E402

from rtchannel.errors import SceneFileError  # noqa: E402
from rtchannel.scene.sandbox import check_scene_file, load_error_line  # noqa: E402

ROOM = SCENES["room"].read_text()


def _scene(tmp_path, extra: str, name="s.xml"):
    d = tmp_path / "scene"
    d.mkdir(exist_ok=True)
    p = d / name
    p.write_text(ROOM.replace("</scene>", extra + "\n</scene>"))
    return p


@pytest.fixture
def secret(tmp_path):
    s = tmp_path / "secret.txt"
    s.write_text("TOP-SECRET first line\n")
    return s


@pytest.mark.parametrize("extra", [
    '<include filename="{rel}"/>',
    '<include filename="{abs}"/>',
    '<shape type="ply" id="x"><string name="filename" value="{rel}"/></shape>',
    '<shape type="obj" id="x" filename="{abs}"/>',
    '<default name="f" value="{rel}"/><shape type="ply" id="x"><string name="filename" value="$f"/></shape>',
    '<path value="{dir}"/>',
    '<texture type="bitmap" id="t"><string name="image" value="../secret.txt"/></texture>',
])
def test_scene_cannot_reference_files_outside_its_folder(tmp_path, secret, extra):
    p = _scene(tmp_path, extra.format(rel="../secret.txt", abs=str(secret), dir=str(secret.parent)))
    with pytest.raises(SceneFileError, match=r"line \d+: .* points outside the scene's folder") as exc:
        get_scene(p, "2k", 1.75, 24.125e9)
    assert "TOP-SECRET" not in str(exc.value) and "\n" not in str(exc.value)


def test_symlink_and_nested_include_escapes_are_refused(tmp_path, secret):
    d = tmp_path / "scene"
    d.mkdir()
    (d / "mesh.ply").symlink_to(secret)
    p = _scene(tmp_path, '<shape type="ply" id="x"><string name="filename" value="mesh.ply"/></shape>')
    with pytest.raises(SceneFileError, match="points outside"):
        check_scene_file(p)
    (d / "inner.xml").write_text('<scene version="2.1.0"><include filename="../secret.txt"/></scene>')
    p2 = _scene(tmp_path, '<include filename="inner.xml"/>', name="outer.xml")
    with pytest.raises(SceneFileError, match=r"inner\.xml: line 1: include '\.\./secret\.txt' points outside"):
        check_scene_file(p2)


@pytest.mark.parametrize("text, match", [
    ("<scene><shape type='cube'></scene>", r"line 1, column \d+: malformed XML"),
    ('<!DOCTYPE s [<!ENTITY a "aaaa">]><scene>&a;</scene>', "DTDs and entities are not allowed"),
    ('<!DOCTYPE s SYSTEM "file:///etc/passwd"><scene/>', "DTDs and entities are not allowed"),
    ("<mesh/>", r"not a Mitsuba scene file \(the root element is <mesh>"),
    ('<scene><shape type="ply" id="x"><string name="filename" value="$nope"/></shape></scene>',
     r"\$nope has no <default>"),
    ('<scene><shape type="ply" id="x"><string name="filename" value="missing.ply"/></shape></scene>', "does not exist"),
    ('<scene><include filename="s.xml"/></scene>', "nested deeper than 8 or in a cycle"),
])
def test_malformed_scene_files_are_one_line(tmp_path, text, match):
    d = tmp_path / "scene"
    d.mkdir()
    p = d / "s.xml"
    p.write_text(text)
    with pytest.raises(SceneFileError, match=match) as exc:
        check_scene_file(p)
    assert "\n" not in str(exc.value) and "aaaa" not in str(exc.value)


def test_scene_may_use_its_folder_and_the_project_assets(tmp_path):
    d = tmp_path / "scene"
    d.mkdir()
    shutil.copy(SCENES["room"], d / "base.xml")
    p = _scene(tmp_path, '<include filename="base.xml"/>', name="with_include.xml")
    p.write_text(f'<scene version="2.1.0"><include filename="base.xml"/>'
                 f'<include filename="{SCENES["free_space"]}"/></scene>')
    check_scene_file(p)  # own folder and scenes/: allowed
    for name in SCENES.values():
        check_scene_file(name)


def test_mitsuba_load_error_is_one_line_without_quoted_content(tmp_path):
    p = _scene(tmp_path, '<shape type="no_such_plugin" id="x"/>')
    with pytest.raises(SceneFileError) as exc:
        get_scene(p, "2k", 1.75, 24.125e9)
    msg = str(exc.value)
    assert "\n" not in msg and "could not load the scene" in msg and "no_such_plugin" not in msg
    assert load_error_line("x.xml", RuntimeError('Error at line 3, col 7: bad "secret text"')) == \
        ("x.xml: the ray tracer could not load the scene (line 3, column 7): RuntimeError: Error at line 3, col 7: "
         "bad ...")


# ------------------------------------------------------------------ loading without Sionna RT (facets)
def _user_scene(tmp_path, frequency_range_ok=True):
    """A scene in Sionna's other conventions: an ITU material named by its id (a Blender-style `diffuse`
    BSDF), a radio-material with explicit parameters, default thicknesses, several shape types."""
    ground = "concrete" if frequency_range_ok else "very_dry_ground"  # the latter: 1-10 GHz only
    p = tmp_path / "user.xml"
    p.write_text(f'''<scene version="2.1.0">
        <bsdf type="diffuse" id="mat-itu_{ground}"/>
        <bsdf type="radio-material" id="glassy"><float name="relative_permittivity" value="6.5"/>
            <float name="conductivity" value="0.03"/><float name="thickness" value="0.012"/></bsdf>
        <bsdf type="itu-radio-material" id="board"><string name="type" value="plasterboard"/></bsdf>
        <shape type="rectangle" id="ground"><transform name="to_world"><scale x="5" y="5"/></transform>
            <ref id="mat-itu_{ground}" name="bsdf"/></shape>
        <shape type="rectangle" id="pane"><transform name="to_world"><scale x="2" y="1"/>
            <rotate x="1" angle="90"/><translate y="3" z="1"/></transform><ref id="glassy" name="bsdf"/></shape>
        <shape type="cube" id="cupboard"><transform name="to_world"><scale value="0.4"/>
            <translate x="-2" y="2" z="0.4"/></transform><ref id="board" name="bsdf"/></shape>
    </scene>''')
    return p


def _loaded_both_ways(scene):
    from rtchannel.body.avatar import load_avatar

    av = load_avatar("2k")
    return [RTScene(scene, av.faces, av.vertices, 24.125e9, sionna=s) for s in (False, True)]


@pytest.mark.parametrize("which", ["room", "furnished", "user"])
def test_scene_loaded_without_sionna_is_sionnas_bit_for_bit(which, tmp_path):
    # The facets backend loads scenes with Mitsuba alone (rtchannel.scene.mitsuba_scene, no `import sionna.rt`,
    # 0.4-0.6 s less start-up). Everything it uses must equal what Sionna RT's loader gives, exactly: object
    # names and order, static meshes, walls with their slab parameters, and what rays hit.
    from rtchannel.scene.furniture import Furniture
    from rtchannel.scene.spec import Scene

    scene = {"room": "room", "furnished": Scene.room().with_furniture(Furniture()),
             "user": _user_scene(tmp_path)}[which]
    mine, sionnas = _loaded_both_ways(scene)
    assert mine.sionna_scene is None and sionnas.sionna_scene is not None
    assert list(mine.object_names.values()) == list(sionnas.object_names.values())
    assert mine.object_names[mine.body_object_id] == sionnas.object_names[sionnas.body_object_id] == "body"
    for (n1, v1, f1), (n2, v2, f2) in zip(mine.static_meshes, sionnas.static_meshes, strict=True):
        assert n1 == n2 and np.array_equal(v1, v2) and np.array_equal(f1, f2)
    assert len(mine.walls) == len(sionnas.walls) > 0
    for a, b in zip(mine.walls, sionnas.walls):
        for k in ("name", "point", "normal", "polygon", "relative_permittivity", "thickness", "area"):
            assert np.array_equal(getattr(a, k), getattr(b, k)), (a.name, k)
    rng = np.random.default_rng(1)
    origins = rng.uniform(-3, 3, (4000, 3)) * [1, 1, 0] + [0, 0, 1.0]
    directions = rng.normal(size=(4000, 3))
    hits = [sc.cast(origins, directions) for sc in (mine, sionnas)]
    assert hits[0]["hit"].mean() > 0.4 and hits[0]["body"].any()  # the downward half hits the floor
    for k in hits[0]:
        assert np.array_equal(hits[0][k], hits[1][k]), k


def test_scenes_only_sionna_can_load_fall_back_to_it(tmp_path):
    from rtchannel.scene import mitsuba_scene

    (tmp_path / "inner.xml").write_text(SCENES["room"].read_text())
    p = tmp_path / "outer.xml"
    p.write_text('<scene version="2.1.0"><include filename="inner.xml"/></scene>')
    mine, sionnas = _loaded_both_ways(p)
    assert mine.sionna_scene is not None  # included files keep Sionna's plugin names: its loader
    assert [w.name for w in mine.walls] == [w.name for w in sionnas.walls] == [n for n, _, _ in sionnas.static_meshes]
    with pytest.raises(mitsuba_scene.NeedsSionna):
        mitsuba_scene.rewrite_materials('<scene><bsdf type="absorber-radio-material" id="a"/></scene>')


def test_an_itu_material_whose_type_has_no_value_is_a_scene_error_on_both_loaders(tmp_path):
    # Found by mypy: the Mitsuba-only loader copied the missing value (None) into the rewritten XML, and
    # serialising it raised TypeError (the CLI's internal-error exit, not a one-line user error); Sionna's loader
    # reads it as the material "None" and refuses it. Both must give the same one-line scene error.
    from rtchannel.body.avatar import load_avatar

    p = tmp_path / "typeless.xml"
    p.write_text('<scene version="2.1.0"><bsdf type="itu-radio-material" id="mat-itu_concrete">'
                 '<string name="type"/></bsdf><shape type="cube" id="box"><ref id="mat-itu_concrete" name="bsdf"/>'
                 '</shape></scene>')
    av = load_avatar("2k")
    for sionna in (False, True):
        with pytest.raises(SceneFileError, match=r"typeless\.xml: the ray tracer could not load the scene") as e:
            RTScene(p, av.faces, av.vertices, 24.125e9, sionna=sionna)
        assert "\n" not in str(e.value)


def test_itu_materials_are_sionnas():
    # The table and default thickness used without Sionna must be Sionna's own (a Sionna update that changes
    # them fails here), and a material outside its frequency range is an error either way.
    from sionna.rt.constants import DEFAULT_THICKNESS
    from sionna.rt.radio_materials.itu import ITU_MATERIALS_PROPERTIES

    from rtchannel.scene import mitsuba_scene

    assert mitsuba_scene.ITU_MATERIALS_PROPERTIES == ITU_MATERIALS_PROPERTIES
    assert mitsuba_scene.DEFAULT_THICKNESS == DEFAULT_THICKNESS


def test_itu_material_outside_its_frequency_range_is_an_error(tmp_path):
    from rtchannel.body.avatar import load_avatar

    av = load_avatar("2k")
    p = _user_scene(tmp_path, frequency_range_ok=False)
    for sionna in (False, True):
        with pytest.raises(ValueError, match="not defined for this frequency"):
            RTScene(p, av.faces, av.vertices, 24.125e9, sionna=sionna)


def test_a_scene_loaded_without_sionna_does_not_disturb_sionna_traces():
    # Sionna RT's solver traces method calls over every live Mitsuba BSDF of the process: the stand-in
    # materials of a scene loaded without Sionna must not be among them (mitsuba_scene.load).
    from rtchannel.backends.rcs import PEC, monostatic_rcs, plate_mesh, sionna_backend

    mine, _ = _loaded_both_ways("room")
    v, f = plate_mesh(0.2, 0.2, 2)
    r = monostatic_rcs(sionna_backend(PEC, samples_per_src=20_000, specular=True, diffuse=False), v, f, distance=3.0)
    assert r["n_paths"] == 1 and mine.sionna_scene is None


def test_skin_scattering_coefficient_follows_roughness_in_wavelengths():
    """Kirchhoff: S^2 = 1 - exp(-(4 pi sigma_h / lambda)^2), sigma_h fixed by S = 0.5 at 24.125 GHz. By hand:
    g(24.125 GHz) = -ln(0.75) = 0.2877, so at 5.8 GHz g = 0.2877 (5.8 / 24.125)^2 = 0.01663 and
    S = sqrt(1 - exp(-0.01663)) = 0.1284; sigma_h = sqrt(0.2877) lambda / 4 pi = 0.530 mm."""
    from rtchannel.scene.skin import SkinMaterial, roughness_rms_m, scattering_coefficient

    assert roughness_rms_m() == pytest.approx(0.5304e-3, rel=1e-3)
    assert scattering_coefficient(24.125e9) == 0.5
    assert scattering_coefficient(5.8e9) == pytest.approx(0.1284, abs=5e-4)
    assert scattering_coefficient(77e9) == pytest.approx(np.sqrt(1 - np.exp(-0.2877 * (77 / 24.125) ** 2)), rel=1e-3)
    assert SkinMaterial.at(5.8e9).scattering_coefficient == pytest.approx(0.1284, abs=5e-4)
    assert SkinMaterial.at(5.8e9, scattering_coefficient=0.5).scattering_coefficient == 0.5  # still a knob
