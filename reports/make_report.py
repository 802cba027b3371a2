#!/usr/bin/python3
"""Static HTML report of a `crossdyn verify` run (or of `crossdyn study`: a study.json).

    /usr/bin/python3 reports/make_report.py SUMMARY.json OUT_DIR

Reads the JSON summary that `crossdyn verify --report DIR` writes (summary.json), the runs' CSV
files and each scene's drawing geometry it names (data/<scene>/<run>.csv, data/<scene>/geometry.json),
and writes into OUT_DIR:

    index.html               every scene x kind of check: worst normalised error, PASS/FAIL
    <scene>.html             one page per scene: its picture, data, runs, charts, every check
    <scene>-scene.png        the scene at t = 0 as crossdyn read it (3-D and three projections)
    <scene>-motion.png       the configuration at later times (from the kane run)
    <scene>-*.png            the time-history charts

The pages are rendered from the Jinja2 templates in reports/templates/ and work offline: no scripts,
no web fonts, images are local PNG files. Every file is written to a temporary name and renamed
into place. Charts use matplotlib's Agg backend (Debian python3-matplotlib; run with
/usr/bin/python3). In the JSON summary, null stands for a value that is not a finite number.
"""

import json
import os
import signal
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from crossdyn_report import charts, pages, scene_view  # noqa: E402
from crossdyn_report.common import Run, plt, warn, write_atomic  # noqa: E402


def scene_pictures(scene, out_dir, sid):
    """The scene drawn at t = 0 and at later times: [(file, alt, caption)], note on the run. The
    picture shows the scene's warnings as crossdyn made them (the summary's "warnings" are the
    same list, for the pages)."""
    if not scene.get("geometry"):
        return [], ""
    geom = scene_view.load(os.path.join(out_dir, scene["geometry"]))
    pictures = []
    name = "%s-scene.png" % sid
    write_atomic(os.path.join(out_dir, name), scene_view.initial_png(geom))
    pictures.append(dict(name=name, alt="%s at t = 0" % scene.get("scene"), caption=(
        "The scene at t = 0 as crossdyn read it: a 3-D view (left) and three projections along N's "
        "axes (right), in N, SI units; the conventions are written under the picture. Red marks what "
        "must agree and does not, or a likely mistake; orange, what may be intended or not.")))
    motion = geom.get("motion", {})
    note = ""
    if motion.get("state") != "ok":
        note = scene_view.motion_title(geom)
    if motion.get("frames"):
        name = "%s-motion.png" % sid
        write_atomic(os.path.join(out_dir, name), scene_view.motion_png(geom))
        pictures.append(dict(name=name, alt="%s at later times" % scene.get("scene"), caption=(
            "The configuration at 0, T/3, 2T/3 and T from the %s run (attitudes from its output "
            "columns, positions from the joints, system centre of mass at N's origin), same view "
            "and scale in each panel." % (motion.get("engine") or "kane"))))
    return pictures, note


def scene_page(env, scene, out_dir):
    sid = scene["id"]
    if scene.get("input_error"):
        return pages.render(env, "scene.html", pages.scene_context(scene, [], [], ""))
    runs = [Run(info, out_dir, i) for i, info in enumerate(scene.get("runs", []))]
    try:
        pictures, motion_note = scene_pictures(scene, out_dir, sid)
    except Exception as e:  # a picture that cannot be drawn must not lose the page
        warn("%s: the scene picture failed: %r" % (sid, e))
        plt.close("all")
        pictures, motion_note = [], "The scene picture could not be drawn: %s" % e
    made = []
    for chart in charts.CHARTS:
        try:
            result = chart(scene, runs, out_dir, sid)
        except Exception as e:  # likewise for a chart
            warn("%s: %s failed: %r" % (sid, chart.__name__, e))
            plt.close("all")
            result = None
        if result:
            made.append(dict(name=result[0], caption=result[1]))
    try:
        conv_chart = charts.chart_converge(scene, out_dir, sid)
    except Exception as e:  # a chart that cannot be drawn must not lose the page
        warn("%s: the converge chart failed: %r" % (sid, e))
        plt.close("all")
        conv_chart = None
    converge = pages.converge_context(
        scene, dict(name=conv_chart[0], caption=conv_chart[1]) if conv_chart else None)
    return pages.render(env, "scene.html", pages.scene_context(scene, pictures, made, motion_note, converge))


def write_scene_page(env, scene, out_dir):
    """Writes one scene's page and pictures (the index needs nothing back: the scene's warnings are
    in the summary)."""
    write_atomic(os.path.join(out_dir, scene["page"]), scene_page(env, scene, out_dir))


_worker_env = None


def _worker_start(parent):
    """In each worker: the default SIGTERM (the parent's handler is for the parent), and SIGTERM
    when the parent dies however it dies (Linux prctl PR_SET_PDEATHSIG), so that no worker outlives
    the script and writes on into a folder crossdyn has abandoned."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM, 0, 0, 0)  # PR_SET_PDEATHSIG
    except Exception:  # not Linux: the parent's SIGTERM handler still ends the workers
        pass
    if os.getppid() != parent:  # the parent died before prctl
        os._exit(1)


def _scene_job(job):
    """One scene in a worker process (matplotlib and the templates loaded once per worker)."""
    global _worker_env
    if _worker_env is None:
        _worker_env = pages.environment()
    scene, out_dir = job
    return write_scene_page(_worker_env, scene, out_dir)


def workers(count):
    """Worker processes for `count` scenes: CROSSDYN_REPORT_JOBS if set (1 = one process, no
    workers), else one per CPU."""
    given = os.environ.get("CROSSDYN_REPORT_JOBS", "").strip()
    try:
        n = int(given) if given else (os.cpu_count() or 1)
    except ValueError:
        warn("CROSSDYN_REPORT_JOBS=%r is not a number; using one process" % given)
        n = 1
    return max(1, min(n, count))


def scene_pages(env, scenes, out_dir):
    """Writes every scene's page, in worker processes when there are several CPUs (the pictures and
    charts are most of the report's time and each scene's are independent), else one by one. The
    same files either way. A scene that raises ends the report as it would serially: the exception
    (with the worker's traceback) propagates and the script exits non-zero. On SIGTERM (crossdyn
    interrupted) the workers are ended too, so none writes on into the abandoned folder."""
    n = workers(len(scenes))
    if n == 1:
        return [write_scene_page(env, scene, out_dir) for scene in scenes]

    def terminated(signum, frame):
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, terminated)  # before any worker exists
    try:
        import multiprocessing

        pool = multiprocessing.get_context("fork").Pool(n, initializer=_worker_start, initargs=(os.getpid(),))
    except (ImportError, OSError, ValueError) as e:  # no fork, no semaphores: one process
        signal.signal(signal.SIGTERM, previous)
        warn("no worker processes (%s); drawing the scenes one by one" % e)
        return [write_scene_page(env, scene, out_dir) for scene in scenes]
    try:
        results = pool.map(_scene_job, [(scene, out_dir) for scene in scenes], chunksize=1)
        pool.close()
        return results
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
        signal.signal(signal.SIGTERM, previous)


def study_report(summary, out_dir):
    """The pages of `crossdyn study --report DIR` (study.json, "kind": "study"): index.html, one
    <scene>-study.html per scene with its work-precision chart, and scaling.html."""
    env = pages.environment()
    for scene in summary.get("scenes", []):
        try:
            made = charts.chart_study(scene, out_dir)
        except Exception as e:  # a chart that cannot be drawn must not lose the page
            warn("%s: the study chart failed: %r" % (scene.get("scene"), e))
            plt.close("all")
            made = None
        chart = dict(name=made[0], caption=made[1]) if made else None
        write_atomic(os.path.join(out_dir, scene["page"]),
                     pages.render(env, "study.html", pages.study_scene_context(summary, scene, chart)))
    if summary.get("scaling"):
        made = charts.chart_scaling(summary["scaling"], out_dir)
        chart = dict(name=made[0], caption=made[1]) if made else None
        try:
            made = charts.chart_conditioning(summary["scaling"], out_dir)
        except Exception as e:  # a chart that cannot be drawn must not lose the page
            warn("the conditioning chart failed: %r" % (e,))
            plt.close("all")
            made = None
        cond_chart = dict(name=made[0], caption=made[1]) if made else None
        write_atomic(os.path.join(out_dir, summary["scaling"].get("page", "scaling.html")),
                     pages.render(env, "scaling.html",
                                  pages.scaling_context(summary, chart, cond_chart)))
    write_atomic(os.path.join(out_dir, "index.html"),
                 pages.render(env, "study_index.html", pages.study_index_context(summary)))
    return 0


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    summary_path, out_dir = argv[1], argv[2]
    try:
        with open(summary_path, encoding="utf-8") as f:
            summary = json.load(f)
    except (OSError, ValueError) as e:
        warn("cannot read %s: %s" % (summary_path, e))
        return 2
    os.makedirs(out_dir, exist_ok=True)
    if summary.get("kind") == "study":
        return study_report(summary, out_dir)
    if summary.get("kind") == "linearize":
        from crossdyn_report import linear
        return linear.report(summary, out_dir, pages.environment(), pages.render, warn)
    if summary.get("kind") == "stability":
        from crossdyn_report import stability
        return stability.report(summary, out_dir, pages.environment(), pages.render, warn)
    env = pages.environment()
    scenes = summary.get("scenes", [])
    for scene in scenes:
        scene.setdefault("group_order", summary.get("group_order", []))
    scene_pages(env, scenes, out_dir)
    write_atomic(os.path.join(out_dir, "index.html"),
                 pages.render(env, "index.html", pages.index_context(summary)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
