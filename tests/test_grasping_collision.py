import numpy as np
import pytest
import trimesh

from haptic_env.cache import CacheError
from haptic_env.grasping.collision import CollisionConfig, convex_pieces
from haptic_env.objects import GraspObject, data_dir, load_object_set


def _l_shape():
    a = trimesh.creation.box([0.08, 0.02, 0.02])
    b = trimesh.creation.box([0.02, 0.08, 0.02])
    b.apply_translation([0.03, 0.03, 0])
    return GraspObject("ell", trimesh.boolean.union([a, b], engine="manifold"))


def test_convex_object_uses_hull():
    obj = GraspObject("box", trimesh.creation.box([0.05, 0.06, 0.07]))
    pieces = convex_pieces(obj)
    assert len(pieces) == 1 and np.isclose(pieces[0].volume, obj.mesh.volume)


def test_coacd_decomposition_is_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))
    obj = _l_shape()
    cfg = CollisionConfig(threshold=0.05)
    p1 = convex_pieces(obj, cfg)
    files = list((tmp_path / "collision").glob("*.npz"))
    assert len(files) == 1 and len(p1) >= 2
    assert all(np.isclose(abs(p.volume), p.convex_hull.volume, rtol=0.02) for p in p1)  # convex pieces
    p2 = convex_pieces(obj, cfg)
    assert len(p2) == len(p1) and all(np.allclose(a.vertices, b.vertices) for a, b in zip(p1, p2))
    files[0].write_bytes(b"garbage")
    with pytest.raises(CacheError, match="corrupted"):
        convex_pieces(obj, cfg)
    # cache=False neither reads (the corrupted file is still there) nor writes, nor needs the cache folder (below:
    # one that cannot be created)
    p_no = convex_pieces(obj, cfg, cache=False)
    assert len(p_no) == len(p1) and files[0].read_bytes() == b"garbage"
    blocked = tmp_path / "a_file"
    blocked.write_text("")
    monkeypatch.setenv("HAPTIC_CACHE", str(blocked / "cache"))
    p3 = convex_pieces(obj, cfg, cache=False)
    assert len(p3) == len(p1) and all(np.allclose(a.vertices, b.vertices) for a, b in zip(p1, p3))


def test_shipped_ycb_pieces_align_with_mesh():
    if data_dir() is None or not (data_dir() / "ycb" / "025_mug").is_dir():
        pytest.skip("shared data (ycb/025_mug) absent; set HAPTIC_DATA to the data folder")
    mug = load_object_set("ycb10")["025_mug"]
    pieces = convex_pieces(mug)
    assert len(pieces) == len(mug.collision_paths) > 1
    bounds = np.array([p.bounds for p in pieces])
    lo, hi = bounds[:, 0].min(0), bounds[:, 1].max(0)
    assert np.allclose(lo, mug.mesh.bounds[0], atol=5e-3) and np.allclose(hi, mug.mesh.bounds[1], atol=5e-3)


def test_bad_method():
    with pytest.raises(ValueError, match="collision method"):
        CollisionConfig(method="voxels")


def test_shipped_pieces_of_a_millimetre_folder_are_in_metres_like_their_mesh(tmp_path):
    """A folder in the YCB layout (``<object>/mesh.stl`` + ``collision_*.stl``) loaded with ``units="mm"``: the pieces
    are scaled, turned and moved as the mesh was (they stayed in millimetres, 1000 times too large)."""
    from haptic_env.objects.loaders import load_folder

    box = trimesh.creation.box((60.0, 60.0, 100.0))
    box.apply_translation((0, 0, 50.0))  # in the file: standing on z = 0, in millimetres
    (tmp_path / "box").mkdir()
    box.export(tmp_path / "box" / "mesh.stl")
    box.export(tmp_path / "box" / "collision_00.stl")
    obj = load_folder(tmp_path, units="mm")[0]
    pieces = convex_pieces(obj)
    np.testing.assert_allclose(pieces[0].bounds, obj.mesh.bounds, atol=1e-9)
    assert obj.unit_scale == 1e-3
    objects = load_folder(tmp_path, units="mm")  # its pools, built with pieces in mm before, get a new key
    metres = load_folder(tmp_path, units=1e-3 * (1 + 1e-9))  # the same files in other units: another key
    assert objects.identity[0][:2] == ("box", obj.mesh_hash) and objects.identity[0][2].startswith("pieces ")
    assert objects.identity[0][2] != metres.identity[0][2]


def _shipped(tmp_path, piece: trimesh.Trimesh):
    from haptic_env.objects.loaders import load_folder

    (tmp_path / "obj").mkdir()
    piece.export(tmp_path / "obj" / "mesh.stl")  # the object ships its own mesh as its one "piece", as YCB's drill
    piece.export(tmp_path / "obj" / "collision_00.stl")
    return load_folder(tmp_path)[0]


def test_hull_depth_is_zero_on_the_hull_and_the_nearest_face_inside():
    from haptic_env.grasping.collision import hull_depth

    box = trimesh.creation.box((0.06, 0.06, 0.1))
    assert hull_depth(box.vertices, box.convex_hull) == pytest.approx(0.0, abs=1e-12)
    assert hull_depth(box.triangles_center, box.convex_hull) == pytest.approx(0.0, abs=1e-12)
    inside = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.04]])  # 0.03 and 0.01 from the nearest face
    assert hull_depth(inside, box.convex_hull) == pytest.approx(0.03)
    assert hull_depth(np.empty((0, 3)), box.convex_hull) == 0.0


def test_a_non_convex_shipped_piece_is_decomposed_not_collided_as_its_hull(tmp_path, monkeypatch, caplog):
    """YCB's drill ships its whole (non-convex) mesh as one "piece"; MuJoCo would collide its hull. The object is
    decomposed instead (logged); ``method="files"`` keeps the piece as shipped."""
    import logging

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    obj = _shipped(tmp_path, _l_shape().mesh)
    with caplog.at_level(logging.INFO, logger="haptic_env.grasping.collision"):
        pieces = convex_pieces(obj, CollisionConfig(threshold=0.05))
    assert "collision_00.stl" in caplog.text and "not convex" in caplog.text
    assert len(pieces) >= 2 and list((tmp_path / "cache" / "collision").glob("*.npz"))
    import json

    from haptic_env.grasping import collision

    (verdict,) = (tmp_path / "cache" / "collision").glob("*-convexity-*.json")
    assert json.loads(verdict.read_text())["non_convex"].startswith("collision_00.stl")
    called = []
    monkeypatch.setattr(collision, "_non_convex_piece", lambda *a: called.append("test"))
    monkeypatch.setattr(collision, "_from_files", lambda *a: called.append("load"))
    again = convex_pieces(obj, CollisionConfig(threshold=0.05))  # the cached verdict: neither loaded nor tested
    assert len(again) == len(pieces) and not called
    monkeypatch.undo()
    kept = convex_pieces(obj, CollisionConfig(method="files"))
    assert len(kept) == 1


def test_a_convex_shipped_piece_is_used_as_shipped(tmp_path, monkeypatch):
    """... and the verdict is cached: a second call (another process, another pool chunk) does not test the pieces
    again; an unreadable verdict file is tested again, with a warning; ``cache=False`` writes none."""
    from haptic_env.grasping import collision

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    obj = _shipped(tmp_path, trimesh.creation.box((0.06, 0.06, 0.1)))
    assert len(convex_pieces(obj, cache=False)) == 1 and not (tmp_path / "cache" / "collision").exists()
    pieces = convex_pieces(obj)
    verdicts = list((tmp_path / "cache" / "collision").glob("*-convexity-*.json"))
    assert len(pieces) == 1 and len(verdicts) == 1 and not list((tmp_path / "cache" / "collision").glob("*.npz"))
    tested = []
    real = collision._non_convex_piece
    monkeypatch.setattr(collision, "_non_convex_piece", lambda *a: tested.append(1) or real(*a))
    again = convex_pieces(obj)
    assert not tested and np.allclose(again[0].vertices, pieces[0].vertices)
    verdicts[0].write_text("{not json")
    with pytest.warns(RuntimeWarning, match="convexity verdict .* unreadable"):
        assert len(convex_pieces(obj)) == 1
    assert tested == [1] and '"non_convex": null' in verdicts[0].read_text()  # tested and saved again


def test_a_missing_shipped_piece_is_named_when_a_cache_key_reads_it(tmp_path):
    obj = _shipped(tmp_path, trimesh.creation.box((0.06, 0.06, 0.1)))
    obj.collision_paths[0].unlink()
    with pytest.raises(FileNotFoundError, match=r"collision piece .*collision_00\.stl of object 'obj' is missing"):
        obj.pieces_hash
