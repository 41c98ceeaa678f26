"""The project's MJCF files (``assets/``, installed as ``haptic_env.assets``): they load, they are what the code
builds, and the grasp scene's keyframes grasp the mug."""

from __future__ import annotations

import tomllib
from pathlib import Path

import mujoco
import numpy as np
import pytest
from setuptools import find_packages

from haptic_env.assets import ASSETS, HAND_FILES, SCENE_FILE, asset_path, grasp_scene, write_assets
from haptic_env.cli import main
from haptic_env.grasping.hands import HandUnavailableError, generic_hand

ROOT = Path(__file__).resolve().parents[1]
REGENERATE = "the file and the code disagree: regenerate the assets with `python -m haptic_env.assets`"
#: compiled-model arrays that pin a hand: its bodies, joints, geoms, actuators and their physics
HAND_ARRAYS = ("body_parentid", "body_pos", "body_quat", "body_mass", "body_inertia", "jnt_type", "jnt_axis",
               "jnt_range", "dof_damping", "dof_armature", "geom_type", "geom_size", "geom_pos", "geom_quat",
               "geom_contype", "geom_conaffinity", "actuator_trnid", "actuator_ctrlrange", "actuator_gainprm",
               "actuator_biasprm")


def names(m: mujoco.MjModel, kind: str, count: int) -> list[str]:
    return [getattr(m, kind)(i).name for i in range(count)]


def tips_touching(m: mujoco.MjModel, d: mujoco.MjData) -> set[str]:
    """Fingertip bodies of the scene's hand in contact with the object's pieces."""
    obj = {i for i in range(m.ngeom) if m.geom(i).name.startswith("obj")}
    tips = {m.body(f"hand/f{i}_tip").id: f"f{i}" for i in range(4)}
    out = set()
    for c in d.contact[: d.ncon]:
        for a, b in ((c.geom[0], c.geom[1]), (c.geom[1], c.geom[0])):
            if a in obj and m.geom_bodyid[b] in tips:
                out.add(tips[m.geom_bodyid[b]])
    return out


@pytest.mark.parametrize("n", sorted(HAND_FILES))
def test_generic_hand_file_is_the_code(n):
    m_file = mujoco.MjModel.from_xml_path(str(asset_path(HAND_FILES[n])))
    m_code = generic_hand(n).spec.compile()
    for kind, count in (("body", "nbody"), ("joint", "njnt"), ("actuator", "nu")):
        assert names(m_file, kind, getattr(m_file, count)) == names(m_code, kind, getattr(m_code, count)), REGENERATE
    for field in HAND_ARRAYS:
        np.testing.assert_allclose(getattr(m_file, field), getattr(m_code, field), rtol=1e-5, atol=1e-9,
                                   err_msg=f"{HAND_FILES[n]}: {field}; {REGENERATE}")


def test_grasp_scene_file_grasps_the_mug():
    m = mujoco.MjModel.from_xml_path(str(asset_path(SCENE_FILE)))
    d = mujoco.MjData(m)
    assert names(m, "key", m.nkey) == ["approach", "grasp"]
    hand = generic_hand(4).spec.compile()
    assert [a.removeprefix("hand/") for a in names(m, "actuator", m.nu)] == names(hand, "actuator", hand.nu)
    assert m.body("object").id > 0 and m.nmocap == 1
    # the state the backend read its grasp from: all four fingertips on the mug
    mujoco.mj_resetDataKeyframe(m, d, m.key("grasp").id)
    mujoco.mj_forward(m, d)
    assert tips_touching(m, d) == {"f0", "f1", "f2", "f3"}
    # the open hand at the pre-grasp pose, not touching; played for 0.4 s it closes on the mug
    mujoco.mj_resetDataKeyframe(m, d, m.key("approach").id)
    mujoco.mj_forward(m, d)
    assert tips_touching(m, d) == set()
    mujoco.mj_step(m, d, nstep=int(round(0.4 / m.opt.timestep)))
    assert len(tips_touching(m, d)) >= 3


def test_write_assets_rebuilds_the_same_files(tmp_path):
    """Regenerated from the code (the mug's collision pieces decomposed afresh), every file compiles into the
    committed file's bodies, joints, actuators and keyframes."""
    paths = write_assets(tmp_path)
    assert sorted(p.name for p in paths) == sorted([*HAND_FILES.values(), SCENE_FILE])
    for p in paths:
        assert p.stat().st_mode & 0o777 == 0o644
        new, old = mujoco.MjModel.from_xml_path(str(p)), mujoco.MjModel.from_xml_path(str(asset_path(p.name)))
        for kind, count in (("body", "nbody"), ("joint", "njnt"), ("actuator", "nu"), ("key", "nkey")):
            assert names(new, kind, getattr(new, count)) == names(old, kind, getattr(old, count)), REGENERATE
        for field in ("key_qpos", "key_ctrl", "key_mpos", "key_mquat"):  # the grasp's state, as the backend reads it
            np.testing.assert_allclose(getattr(new, field), getattr(old, field), atol=1e-5,
                                       err_msg=f"{p.name}: {field}; {REGENERATE}")
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes leave no temporary files


def test_scene_command_writes_a_scene_that_opens_anywhere(tmp_path, capsys, monkeypatch):
    out = tmp_path / "can.xml"
    assert main(["scene", "--object", "can", "--action", "0,0.8,0,0.5", "--out", str(out)]) == 0
    assert "fingertips touch can" in capsys.readouterr().out
    monkeypatch.chdir(tmp_path.parent)  # loaded from another folder
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("grasp").id)
    mujoco.mj_forward(m, d)
    assert len(tips_touching(m, d)) >= 3
    assert out.stat().st_mode & 0o777 == 0o644


@pytest.mark.parametrize("argv, message", [
    (["--object", "nope"], r"no object 'nope' in the set 'default'; it has \['box'"),
    (["--action", "0,1"], r"--action must be 4 comma-separated numbers, got '0,1'"),
    (["--action", "0,a,0,0"], r"--action must be 4 comma-separated numbers"),
    (["--action", "0,2,0,0"], r"elevation\) = 2.0 is outside \[-1, 1\]"),
])
def test_scene_command_names_bad_input(argv, message, capsys, tmp_path):
    out = tmp_path / "s.xml"
    with pytest.raises(SystemExit) as exc:
        main(["scene", *argv, "--out", str(out)])
    assert exc.value.code == 2
    import re

    assert re.search(message, capsys.readouterr().err)
    assert not out.exists()  # nothing half-written


def test_scene_object_is_the_mug_or_a_set_s_mug_or_its_first():
    from haptic_env.assets import scene_object

    assert scene_object(["box", "mug", "can"]) == "mug"
    assert scene_object(["001_chips_can", "025_mug", "048_hammer"]) == "025_mug"  # ycb10
    assert scene_object(["CatLying", "GreenCup"]) == "CatLying"


def test_scene_command_names_missing_data_without_an_object_too(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("HAPTIC_DATA", str(tmp_path))  # no kit/ there; the default object is looked up in the set
    with pytest.raises(SystemExit) as exc:
        main(["scene", "--objects", "kit8", "--out", str(tmp_path / "s.xml")])
    assert exc.value.code == 2 and "KIT meshes missing" in capsys.readouterr().err


def test_scene_command_names_missing_data(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("HAPTIC_DATA", str(tmp_path))  # no kit/ there
    with pytest.raises(SystemExit) as exc:
        main(["scene", "--objects", "kit8", "--object", "GreenCup", "--out", str(tmp_path / "s.xml")])
    assert exc.value.code == 2 and "KIT meshes missing" in capsys.readouterr().err


def test_scene_command_refuses_a_folder(tmp_path, capsys, monkeypatch):
    with pytest.raises(SystemExit):
        main(["scene", "--out", str(tmp_path)])
    assert "is a folder" in capsys.readouterr().err
    (tmp_path / "grasp_scene.xml").mkdir()  # the default --out is checked as a given one is, before the grasp
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(["scene"])
    assert exc.value.code == 2 and "grasp_scene.xml is a folder" in capsys.readouterr().err
    (tmp_path / "file").write_text("x")
    with pytest.raises(SystemExit) as exc:  # a path under a file was refused only after the grasp
        main(["scene", "--out", str(tmp_path / "file" / "s.xml")])
    assert exc.value.code == 2 and "is not a writable folder" in capsys.readouterr().err


def test_a_menagerie_hand_scene_references_its_meshes_by_absolute_path(tmp_path, monkeypatch):
    try:
        xml, res = grasp_scene("allegro", "default", "can", (0.0, 0.8, 0.0, 0.5))
    except HandUnavailableError as exc:
        pytest.skip(f"allegro hand unavailable (menagerie data absent, no download): {exc}")
    path = tmp_path / "allegro.xml"
    path.write_text(xml)
    monkeypatch.chdir(tmp_path)
    m = mujoco.MjModel.from_xml_path(str(path))
    assert m.nmesh > 0 and res.contacts.shape == (4, 3)


def test_asset_path_names_a_missing_file():
    with pytest.raises(FileNotFoundError, match=r"no asset 'nope\.xml'.*grasp_scene\.xml"):
        asset_path("nope.xml")


def test_every_package_is_installed_and_the_assets_ship():
    """pyproject lists the packages by name (the assets folder is mapped in): none of the source tree is left out,
    and the assets' files are package data."""
    tool = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = set(find_packages(str(ROOT), include=["haptic_env*", "agents*"]))
    assert found <= set(tool["packages"]), f"packages missing from pyproject.toml: {sorted(found - set(tool['packages']))}"
    assert tool["package-dir"]["haptic_env.assets"] == "assets"
    assert ASSETS == ROOT / "assets" or (ASSETS / SCENE_FILE).is_file()
    assert tool["package-data"]["haptic_env.assets"] == ["*.xml"]
