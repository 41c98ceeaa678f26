"""benchmarks/family_cups.py's cup geometry on the embedded default mug (known shape, no shared data needed)."""

from __future__ import annotations

import numpy as np

from haptic_env.objects import load_object_set


def test_cup_profile_finds_the_default_mugs_axis_and_radius(load_benchmark):
    """The mug (objects/primitives.py): outer radius 41 mm, its handle along +x, so its axis lies 41 mm in from -x."""
    bench = load_benchmark("family_cups")
    mesh = load_object_set("default")["mug"].mesh
    c, z0, R = bench.cup_profile(mesh)
    lo, hi = mesh.bounds
    np.testing.assert_allclose(c, [lo[0] + 0.041, 0.0], atol=5e-4)
    mid = (z0 > lo[2] + 0.01) & (z0 < hi[2] - 0.01)
    np.testing.assert_allclose(R[mid], 0.041, atol=1e-3)  # the handle's sectors are left out


def test_cup_contacts_class_handle_inside_and_outer_wall(load_benchmark):
    bench = load_benchmark("family_cups")
    mesh = load_object_set("default")["mug"].mesh
    lo, hi = mesh.bounds
    ax = np.array([lo[0] + 0.041, 0.0])
    zm = (lo[2] + hi[2]) / 2
    outer = [ax[0] - 0.041, 0.0, zm]            # the wall opposite the handle
    handle = [hi[0] - 0.001, 0.0, zm]           # the handle's outermost point
    inner = [ax[0] - 0.036, 0.0, zm]            # the inner wall (5 mm wall)
    bottom_in = [ax[0], 0.0, lo[2] + 0.008]     # the inner bottom (8 mm thick)
    bottom_out = [ax[0], 0.0, lo[2]]
    C = np.array([[outer, outer, bottom_out, outer], [outer, handle, outer, outer],
                  [outer, inner, outer, outer], [bottom_in, outer, outer, outer]])
    on_handle, inside = bench.cup_contacts(mesh, C)
    assert on_handle.tolist() == [False, True, False, False]
    assert inside.tolist() == [False, False, True, True]
