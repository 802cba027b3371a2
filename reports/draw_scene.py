#!/usr/bin/python3
"""A picture of a scene as crossdyn read it (`crossdyn draw SCENE` runs this).

    /usr/bin/python3 reports/draw_scene.py GEOMETRY.json OUT.png

GEOMETRY.json is the drawing geometry crossdyn writes (format in crossdyn_report/scene_view.py).
OUT.png: the scene at t = 0 in 3-D over a row of later configurations; written atomically.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from crossdyn_report import scene_view  # noqa: E402
from crossdyn_report.common import write_atomic  # noqa: E402


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        geom = scene_view.load(argv[1])
    except (OSError, ValueError) as e:
        print("draw_scene.py: cannot read %s: %s" % (argv[1], e), file=sys.stderr)
        return 2
    write_atomic(argv[2], scene_view.combined_png(geom))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
