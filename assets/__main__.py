"""``python -m haptic_env.assets [FOLDER]``: (re)write the project's MJCF files (default: the package's own folder)."""

import sys

from haptic_env.assets import write_assets

for path in write_assets(sys.argv[1] if len(sys.argv) > 1 else None):
    print(path)
