"""``python -m haptic_env.assets [FOLDER]``: (re)write the project's MJCF files (default: the package's own folder)."""

import argparse

from haptic_env.assets import write_assets

parser = argparse.ArgumentParser(prog="python -m haptic_env.assets", description=__doc__.split(": ", 1)[1])
parser.add_argument("folder", nargs="?", default=None, help="where to write them (default: the package's own folder)")
for path in write_assets(parser.parse_args().folder):
    print(path)
