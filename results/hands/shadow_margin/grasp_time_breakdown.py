"""Where a hand grasp's time goes: timers around the grasp scene's parts over N approaches per ycb10 object, one core.

    OMP_NUM_THREADS=1 python results/hands/shadow_margin/grasp_time_breakdown.py shadow 100   # likewise aero 60

(The timers' own overhead inflates the small parts a little.)
"""
import time, numpy as np, sys, collections
from haptic_env.objects import load_object_set
from haptic_env.grasping import make_backend
from haptic_env.grasping import mujoco_backend as mb
from haptic_env.hand_grasps import pool_actions
import mujoco
hand = sys.argv[1]; N = int(sys.argv[2])
acc = collections.Counter()
def wrap(cls, name):
    f = getattr(cls, name)
    def g(*a, **k):
        t = time.perf_counter(); r = f(*a, **k); acc[name] += time.perf_counter() - t; return r
    setattr(cls, name, g)
for nm in ("hand_blocking_contacts", "set_mount", "reset", "step", "tip_touched", "hold_fingers"):
    wrap(mb.GraspScene, nm)
wrap(mb.MujocoBackend, "_read")
objs = load_object_set("ycb10")
be = make_backend("mujoco", n_fingers=None if hand!="allegro" else 4, hand=hand, support="table", normals=True)
rng = np.random.default_rng(0); tot=0
for k in range(len(objs)):
    be.set_object(objs[k]); acts = pool_actions(0, k, N)
    t = time.perf_counter()
    for a in acts: be.grasp(a, rng)
    tot += time.perf_counter() - t
n = N*len(objs)
print(f"{hand}: {n/tot:.1f} g/s; per grasp {1e3*tot/n:.3f} ms")
for k, v in acc.most_common(): print(f"  {k:24s} {1e3*v/n:.3f} ms  {100*v/tot:.1f}%")
print(f"  other {1e3*(tot-sum(acc.values()))/n:.3f} ms")
