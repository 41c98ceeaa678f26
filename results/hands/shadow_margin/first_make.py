"""Time a registered env's first make from an empty cache, then a later make in a new process.

    HAPTIC_CACHE=$(mktemp -d) python results/hands/shadow_margin/first_make.py HapticRecogShadow-v0
"""
import subprocess
import sys
import time

env_id = sys.argv[1] if len(sys.argv) > 1 else "HapticRecogShadow-v0"
CODE = f"""
import time
t0 = time.perf_counter()
import gymnasium as gym, haptic_env
env = gym.make({env_id!r})
env.reset(seed=0)
print(f"{{time.perf_counter() - t0:.1f}}")
"""
times = []
for _ in range(2):
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CODE], check=True, capture_output=True, text=True).stdout
    times.append((float(out.split()[-1]), time.perf_counter() - t))
print(f"{env_id}: FIRST make+reset {times[0][0]:.1f} s (process {times[0][1]:.1f} s, imports included); "
      f"later make+reset {times[1][0]:.1f} s (process {times[1][1]:.1f} s)")
