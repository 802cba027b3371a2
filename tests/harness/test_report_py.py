"""Tests of the report and drawing scripts (reports/crossdyn_report), run by ctest with Debian's
/usr/bin/python3:

    CROSSDYN=build/crossdyn CROSSDYN_SOURCE_DIR=. /usr/bin/python3 -B -m unittest -v test_report_py

They assert what a reader of the report relies on: the joint angles drawn for spherical joints are
the joint rotation the engines integrate (checked against kane's own revolute angle column, offset
included), the index counts passed / failed / unreadable scenes exactly and names the failing
checks in its text, a page has no column for a feature its scene lacks, the joints chart colours
joints and dashes runs with its legend outside the data, and the scene picture flags a child
folded into its parent.
"""

import html
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import unittest

import numpy as np

SOURCE = os.environ.get("CROSSDYN_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(SOURCE, "reports"))

from crossdyn_report import charts, kinematics, pages, scene_view  # noqa: E402
from crossdyn_report.common import Run  # noqa: E402

CROSSDYN = os.environ.get("CROSSDYN", os.path.join(SOURCE, "build", "crossdyn"))


def quat(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * a])


def visible(page):
    """The text of a page a reader sees: tags and their attributes (tooltips) removed."""
    text = re.sub(r"</(td|th|li|p|h1|h2|tr|div|small|pre)>", " ", page)
    text = re.sub(r"<[^>]*>", "", text)
    return html.unescape(re.sub(r"\s+", " ", text))


class FakeRun(Run):
    """A run from arrays instead of a CSV file."""

    def __init__(self, label, columns, data, index=0):
        super().__init__({"label": label, "engine": label}, "", index)
        self.columns, self.data = list(columns), np.asarray(data, float)


class Kinematics(unittest.TestCase):
    def test_rotation_vector_is_axis_times_angle(self):
        axis = np.array([1.0, 2.0, 2.0]) / 3.0
        for angle in (0.0, 1e-9, 0.7, 3.0, math.pi - 1e-9):
            q = quat(axis, angle)[None, :]
            np.testing.assert_allclose(kinematics.rotation_vector(q)[0], angle * axis, rtol=0, atol=1e-14)
            # q and -q are the same rotation.
            np.testing.assert_allclose(kinematics.rotation_vector(-q)[0], angle * axis, rtol=0, atol=1e-14)

    def test_joint_rotation_from_attitudes_undoes_the_offset(self):
        # R_NC = R_NP R_offset Rot(axis_J, theta): the joint rotation is theta about axis_J,
        # whatever the parent's attitude.
        q_NP = quat([0.3, -0.5, 0.8], 1.1)
        q_off = quat([0, 0, 1], math.pi / 2)
        axis_J = np.array([0.0, -1.0, 0.0])
        thetas = np.linspace(-2.5, 2.5, 11)
        mul = kinematics.multiply
        rows = []
        for th in thetas:
            q_NC = mul(mul(q_NP[None, :], q_off[None, :]), quat(axis_J, th)[None, :])[0]
            rows.append(np.concatenate([[th], q_NP, q_NC]))
        run = FakeRun("kane", ["t", "p.qw", "p.qx", "p.qy", "p.qz", "c.qw", "c.qx", "c.qy", "c.qz"], rows)
        system = {"bodies": [{"name": "p"}, {"name": "c"}]}
        joint = {"name": "j", "parent": "p", "child": "c", "orientation_offset_q": list(q_off)}
        phi = kinematics.joint_rotation_vectors(run, system, joint)
        np.testing.assert_allclose(phi, thetas[:, None] * axis_J[None, :], rtol=0, atol=1e-13)
        # The free joint has no parent body: nothing to draw.
        self.assertIsNone(kinematics.joint_rotation_vectors(run, system, dict(joint, parent="N (inertial)")))

    def test_joint_rotation_is_the_engines_own_angle(self):
        # kane's attitudes of the hinged panels (a hinge with a 180 deg offset, one without) give
        # back kane's own angle column: the formula of the spherical-joint chart, checked on data.
        scene = os.path.join(SOURCE, "tests", "harness", "scenes", "hinged_panels.yaml")
        with tempfile.TemporaryDirectory() as tmp:
            csv = os.path.join(tmp, "kane.csv")
            summary = os.path.join(tmp, "summary.json")
            subprocess.run([CROSSDYN, "run", scene, "--engine", "kane", "-o", csv], check=True)
            subprocess.run([CROSSDYN, "compare", scene, "--engines", "kane", "--allow-no-comparison", "--json", summary], check=True,
                           stdout=subprocess.DEVNULL)
            with open(summary, encoding="utf-8") as f:
                system = json.load(f)["scenes"][0]["system"]
            run = Run({"label": "kane", "engine": "kane", "data": "kane.csv"}, tmp, 0)
        self.assertGreater(run.data.shape[0], 100)
        checked = 0
        for joint in system["joints"]:
            if joint["type"] != "revolute":
                continue
            phi = kinematics.joint_rotation_vectors(run, system, joint)
            q_off = np.asarray(joint.get("orientation_offset_q", [1, 0, 0, 0]), float)
            R_off = rotation_matrix(q_off)
            axis_J = R_off.T @ np.asarray(joint["axis"], float)
            angle = run.col(joint["name"] + ".angle")
            self.assertGreater(np.ptp(angle), 0.05)  # the hinge moves
            np.testing.assert_allclose(phi, angle[:, None] * axis_J[None, :], rtol=0, atol=1e-8)
            checked += 1
        self.assertEqual(checked, 2)


def rotation_matrix(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def check(quantity, group, status, a="lagrange", b="kane", normalised=0.1):
    return {"quantity": quantity, "group": group, "a": a, "b": b, "tolerance_key": "default", "atol": 1e-8,
            "rtol": 1e-8, "scale": 1.0, "bound": 2e-8, "error": normalised * 2e-8, "time": 1.5,
            "first_exceeded": 0.5 if status == "FAIL" else None, "normalised": normalised, "status": status,
            "note": ""}


def group(name, status, worst, worst_check, failed=0):
    return {"group": name, "status": status, "worst": worst, "worst_check": worst_check, "checks": 1,
            "failed": failed, "excluded": 0, "skipped": 0}


def summary_three_scenes():
    system = {"name": "s", "description": "d", "source": "src", "zero_linear_momentum": True, "analytic": "",
              "bodies": [{"name": "main", "mass_kg": 1.0, "inertia_kg_m2": [[1, 0, 0], [0, 2, 0], [0, 0, 3]]}],
              "joints": [{"name": "base", "type": "free", "parent": "N (inertial)", "child": "main",
                          "initial": {"w_NB_B_rad_s": [1, 0, 0], "q_NB": [1, 0, 0, 0]}}],
              "run": {"duration_s": 1, "output_step_s": 0.1, "integrator": "rkf78"},
              "compare": {"default": {"atol": 1e-8, "rtol": 1e-8}, "tolerances": [], "excluded": []}}
    runs = [{"label": "kane", "engine": "kane", "state": "ok", "note": "", "rows": 11, "rhs_calls": 10,
             "steps": 2, "wall_seconds": 0.01, "data": "data/good/kane.csv"},
            {"label": "lagrange", "engine": "lagrange", "state": "ok", "note": "", "rows": 11, "rhs_calls": 10,
             "steps": 2, "wall_seconds": 0.01, "data": "data/good/lagrange.csv"}]
    good = {"id": "good", "scene": "good", "page": "good.html", "path": "good.yaml", "passed": True,
            "system": system, "runs": runs, "settings": {"duration_s": 1, "output_step_s": 0.1},
            "checks": [check("main.wx", "w", "PASS"), check("hinge.rate", "rate", "PASS")],
            "groups": [group("w", "PASS", 0.1, "main.wx lagrange vs kane"),
                       group("rate", "PASS", 0.1, "hinge.rate lagrange vs kane")], "notes": []}
    bad = dict(good, id="bad", scene="bad", page="bad.html", passed=False,
               checks=[check("main.wx", "w", "FAIL", normalised=4.6e2)],
               groups=[group("w", "FAIL", 4.6e2, "main.wx lagrange vs kane", failed=1)])
    unreadable = {"id": "broken", "scene": "broken", "page": "broken.html", "path": "broken.yaml",
                  "passed": False, "input_error": "broken.yaml:2:3: bodies: expected a list"}
    return {"tool": "crossdyn", "passed": False, "group_order": ["run", "t", "w", "attitude", "rate", "angle",
                                                                "modal", "H", "E", "H.drift", "E.drift", "extra"],
            "counts": {"scenes": 3, "scenes_failed": 1, "scenes_unreadable": 1, "checks": 3, "checks_failed": 1},
            "scenes": [good, bad, unreadable]}


class Pages(unittest.TestCase):
    def setUp(self):
        self.env = pages.environment()

    def test_index_counts_scenes_and_names_the_failures(self):
        html = pages.render(self.env, "index.html", pages.index_context(summary_three_scenes()))
        text = visible(html)
        self.assertIn("FAIL: 3 scenes: 1 passed, 1 failed (a check did not pass), 1 could not be read.", text)
        self.assertIn("3 checks: 2 passed, 1 failed, 0 excluded, 0 skipped.", text)
        self.assertIn("bad: main.wx, lagrange vs kane: max error 9.200e-06 at t = 1.5 s > bound 2.000e-08", text)
        self.assertIn("broken: could not be read: broken.yaml:2:3: bodies: expected a list", text)
        self.assertIn("error / (atol + rtol * scale)", text)
        self.assertIn("1 or less passes", text)
        # The worst check of a cell is in the cell's text, not only in a tooltip.
        self.assertIn("FAIL 4.6e+02 main.wx lagrange vs kane (1 of 1 failed)", text)
        # A column for rates (one scene has them), "n/a" where a scene has none; no column for
        # kinds of check no scene has (modal coordinates, angles).
        self.assertIn("joint rates", text)
        self.assertIn("n/a no joints with rates", text)
        self.assertNotIn("modal", text)
        self.assertNotIn("joint angles", text)
        self.assertNotIn("<script", html)

    def test_a_scene_with_warnings_is_pointed_at_and_its_warnings_listed(self):
        summary = summary_three_scenes()
        summary["scenes"][0]["warnings"] = [
            {"code": "cm-inboard", "subject": "hinge1", "line": None, "column": None,
             "message": "hinge1: arm's CM is inboard of the joint, inside hub's box: check the sign of "
                        "child_point and the offset"}]
        html = pages.render(self.env, "index.html", pages.index_context(summary))
        self.assertIn('<a href="good.html#warnings">1 scene warning: look at the picture</a>', html)
        self.assertEqual(html.count("1 scene warning: look at the picture"), 1)
        text = visible(html)
        self.assertIn("1 scene warning (below; not failures).", text)
        # The index lists every warning under its scene.
        self.assertIn("Scene warnings", text)
        self.assertIn("good: hinge1: arm's CM is inboard of the joint, inside hub's box: check the sign of "
                      "child_point and the offset [cm-inboard]", text)
        page = pages.render(self.env, "scene.html", pages.scene_context(summary["scenes"][0], [], [], ""))
        self.assertIn("Scene warnings (crossdyn printed these on stderr; not failures): hinge1: arm's CM is "
                      "inboard of the joint", visible(page))
        self.assertIn('id="warnings"', page)
        # No warnings: no section, no marker.
        clean = pages.render(self.env, "index.html", pages.index_context(summary_three_scenes()))
        self.assertNotIn("scene warning:", clean)
        self.assertNotIn("scene warnings (below", visible(clean))
        self.assertNotIn('id="warnings"', clean)

    def test_scene_page_links_csv_and_has_no_empty_columns(self):
        s = summary_three_scenes()["scenes"][1]
        s["group_order"] = []
        html = pages.render(self.env, "scene.html", pages.scene_context(s, [], [], ""))
        text = visible(html)
        self.assertIn('<a href="data/good/kane.csv">CSV</a>', html)
        self.assertIn('<a href="data/good/lagrange.csv">CSV</a>', html)
        self.assertIn("Failed checks main.wx, lagrange vs kane: max error", text)
        self.assertNotIn("flexible modes", text)
        self.assertNotIn("external torque", text)
        self.assertNotIn("loads", text)

    def test_ascii_only_headline_when_all_pass(self):
        summary = summary_three_scenes()
        summary["scenes"] = summary["scenes"][:1]
        summary["counts"] = {"scenes": 1, "scenes_failed": 0, "scenes_unreadable": 0}
        summary["passed"] = True
        text = visible(pages.render(self.env, "index.html", pages.index_context(summary)))
        self.assertIn("ALL PASS: 1 scene: 1 passed, 0 failed (a check did not pass), 0 could not be read.", text)
        self.assertNotIn("What failed", text)


class JointsChart(unittest.TestCase):
    def test_colour_is_the_joint_line_style_the_run_and_the_legend_is_outside(self):
        t = np.linspace(0, 1, 21)
        cols = ["t", "main.qw", "main.qx", "main.qy", "main.qz", "a.qw", "a.qx", "a.qy", "a.qz",
                "h1.angle", "h1.rate", "h2.angle", "h2.rate", "s.wx", "s.wy", "s.wz"]
        runs = []
        for i, label in enumerate(("kane", "lagrange", "newton-euler")):
            q_a = np.array([quat([0, 0, 1], 0.3 * x) for x in t])
            data = np.column_stack([t, np.ones_like(t), 0 * t, 0 * t, 0 * t, q_a, np.sin(t), np.cos(t),
                                    -np.sin(t), -np.cos(t), 0 * t, 0 * t, 0.3 + 0 * t])
            runs.append(FakeRun(label, cols, data, i))
        scene = {"scene": "x", "system": {"bodies": [{"name": "main"}, {"name": "a"}],
                                          "joints": [{"name": "base", "type": "free", "parent": "N (inertial)", "child": "main"},
                                                     {"name": "h1", "type": "revolute", "parent": "main", "child": "a"},
                                                     {"name": "h2", "type": "revolute", "parent": "main", "child": "a"},
                                                     {"name": "s", "type": "spherical", "parent": "main", "child": "a"}]}}
        captured = []
        saved = charts.save_figure
        charts.save_figure = lambda fig, path: captured.append(fig)
        try:
            name, caption = charts.chart_joints(scene, runs, "/nonexistent", "x")
        finally:
            charts.save_figure = saved
        self.assertEqual(name, "x-joints.png")
        self.assertIn("rotation angle", caption)
        fig = captured[0]
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        axes = [ax for ax in fig.axes if ax.get_lines()]
        # Revolute angle, revolute rate, spherical angle, spherical rate, s's rotation vector.
        self.assertEqual(len(axes), 5)
        by_joint, by_run = {}, {}
        for ln in axes[0].get_lines():
            by_joint.setdefault(ln.get_color(), set()).add(str(ln.get_linestyle()))
        self.assertEqual(len(by_joint), 2)  # two joints: two colours ...
        for styles in by_joint.values():
            self.assertEqual(len(styles), 3)  # ... each in the three runs' line styles
        for ln in axes[0].get_lines():
            by_run.setdefault(str(ln.get_linestyle()), set()).add(ln.get_color())
        self.assertEqual(len(by_run), 3)
        # The spherical joint's rotation angle is drawn (0.3 rad about z, from the attitudes).
        np.testing.assert_allclose(axes[2].get_lines()[0].get_ydata(), 0.3 * t, atol=1e-12)
        legends = fig.legends
        self.assertEqual(len(legends), 1)
        box = legends[0].get_window_extent(renderer)
        for ax in axes:
            self.assertFalse(box.overlaps(ax.get_window_extent(renderer)), "the legend covers a chart")


def geometry(child_at, child_point):
    """A hub (2 m cube) with a 1 m cube child hinged at (1, 0, 0) of the hub; child CM at child_at."""
    box = lambda s: {"type": "box", "R_BX": np.eye(3).tolist(), "size_m": [s, s, s]}
    pose = lambda p: {"p_NoBo_N": list(p), "R_NB": np.eye(3).tolist()}
    J = np.array([1.0, 0, 0])
    frame = {"t": 0, "bodies": [pose([0, 0, 0]), pose(child_at)],
             "joints": [{"p_NoJ_N_parent": [0, 0, 0], "p_NoJ_N_child": [0, 0, 0], "gap_m": 0,
                         "axis_N_parent": [0, 0, 0], "axis_N_child": [0, 0, 0], "axis_mismatch_rad": 0},
                        {"p_NoJ_N_parent": list(J), "p_NoJ_N_child": list(np.asarray(child_at) + child_point),
                         "gap_m": float(np.linalg.norm(np.asarray(child_at) + child_point - J)),
                         "axis_N_parent": [0, 0, 1], "axis_N_child": [0, 0, 1], "axis_mismatch_rad": 0}]}
    return {"scene": "g", "bodies": [{"name": "hub", "is_base": True, "shape": box(2.0), "nodes": []},
                                     {"name": "arm", "is_base": False, "shape": box(1.0), "nodes": []}],
            "joints": [{"name": "base", "type": "free", "parent": -1, "child": 0},
                       {"name": "hinge", "type": "revolute", "parent": 0, "child": 1, "axis_P": [0, 0, 1]}],
            "initial": frame, "motion": {"engine": "kane", "state": "failed", "note": "kane: failed at t = 2 s",
                                         "frames": [dict(frame, t=0.0)]}}


class ScenePicture(unittest.TestCase):
    def test_the_picture_prints_the_warnings_crossdyn_made_and_none_of_its_own(self):
        # A child folded into its parent: the picture no longer judges the geometry itself
        # (harness/scene_warnings.cpp does, tests/harness/test_scene_warnings.cpp); it prints the
        # document's "warnings", red, mirror-axes orange, in the order given.
        folded = geometry([0.2, 0, 0], [0.8, 0, 0])
        self.assertEqual(scene_view.scene_warnings(folded), [])
        folded["warnings"] = [
            {"code": "cm-inboard", "subject": "hinge", "line": None, "column": None,
             "message": "hinge: arm's CM is inboard of the joint, inside hub's box: check the sign of "
                        "child_point and the offset"},
            {"code": "mirror-axes", "subject": "a and b", "line": None, "column": None, "message": "a and b ..."}]
        self.assertEqual(scene_view.scene_warnings(folded),
                         [(folded["warnings"][0]["message"], scene_view.MISMATCH),
                          ("a and b ...", scene_view.SYMMETRY)])
        captured = []
        original = scene_view.png_bytes
        scene_view.png_bytes = lambda fig: captured.append(fig) or b""
        try:
            scene_view.initial_png(folded)
        finally:
            scene_view.png_bytes = original
        texts = {t.get_text(): t for t in captured[0].texts}
        red = texts[folded["warnings"][0]["message"]]
        self.assertEqual(matplotlib_colour(red.get_color()), matplotlib_colour(scene_view.MISMATCH))
        self.assertEqual(red.get_weight(), "bold")
        self.assertEqual(matplotlib_colour(texts["a and b ..."].get_color()),
                         matplotlib_colour(scene_view.SYMMETRY))

    def test_every_warning_is_printed_before_the_notes_and_none_is_dropped_for_them(self):
        red = scene_view.MISMATCH
        notes = ["note %d" % k for k in range(6)]
        lines = scene_view.text_lines([("w0", red)], notes)
        self.assertEqual([t for t, *_ in lines], ["w0", "note 0", "note 1", "note 2", "note 3"])
        self.assertEqual({size for *_, size, _ in lines}, {8})  # five lines fit at 8 pt
        lines = scene_view.text_lines([("w%d" % k, red) for k in range(6)], notes)
        self.assertEqual([t for t, *_ in lines], ["w0", "w1", "w2", "w3", "w4", "w5", "note 0", "note 1"])
        self.assertEqual({size for *_, size, _ in lines}, {7})  # eight at 7 pt, in the same room
        self.assertGreater(min(y for *_, y in lines), 0.15)     # above the legend
        lines = scene_view.text_lines([("w%d" % k, red) for k in range(10)], notes)
        self.assertEqual([t for t, *_ in lines][-2:],
                         ["w6", "... and 3 more scene warnings (printed by crossdyn, and in the report)"])

    def test_a_failed_run_still_gives_a_picture_that_says_so(self):
        g = geometry([2.0, 0, 0], [-1.0, 0, 0])
        png = scene_view.combined_png(g)
        self.assertTrue(png.startswith(b"\x89PNG\r\n\x1a\n"))
        self.assertIn("the run failed, so only 1 time can be shown: kane: failed at t = 2 s",
                      scene_view.motion_title(g))
        # A positive angle about +z moves the arm (at +x of the hinge) towards +y.
        self.assertEqual(scene_view.joint_notes(g, g["initial"]),
                         ["hinge: axis (0, 0, 1) in hub, (0, 0, 1) in N; + angle moves arm towards N +y"])


def matplotlib_colour(c):
    from matplotlib.colors import to_rgb
    return tuple(round(x, 6) for x in to_rgb(c))


class CheckScenes(unittest.TestCase):
    """The Basilisk-like hinged panels and two copies with one wrong sign each
    (tests/harness/scenes): crossdyn draw prints each one's warnings on stderr and puts the same
    in the geometry document the picture is drawn from; the correct one has none."""

    def draw(self, name):
        scene = os.path.join(SOURCE, "tests", "harness", "scenes", name + ".yaml")
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "geometry.json")
            r = subprocess.run([CROSSDYN, "draw", scene, "--no-motion", "-o", os.path.join(tmp, "p.png"),
                                "--geometry", out], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
            return scene_view.load(out), r.stderr, scene

    def messages(self, name):
        g, err, scene = self.draw(name)
        warnings = [m for m, _ in scene_view.scene_warnings(g)]
        # The terminal says exactly what the picture says, one line each.
        self.assertEqual([ln for ln in err.splitlines() if ln.startswith("crossdyn: warning: ")],
                         ["crossdyn: warning: %s: %s" % (scene, m) for m in warnings])
        return g, warnings, scene_view.joint_notes(g, g["initial"])

    def test_the_correct_panels_raise_nothing(self):
        g, warnings, notes = self.messages("hinged_panels")
        self.assertEqual(warnings, [])
        self.assertEqual(g["warnings"], [])
        self.assertIn("hinge1: axis (0, -1, 0) in hub, (0, -1, 0) in N (offset); + angle moves panel1 towards N +z",
                      notes)
        self.assertIn("hinge2: axis (0, 1, 0) in hub, (0, 1, 0) in N; + angle moves panel2 towards N +z", notes)

    def test_a_flipped_axis_is_named(self):
        g, warnings, notes = self.messages("hinged_panels_flipped_axis")
        self.assertEqual(warnings, ["hinge1 and hinge2 carry identical bodies at mirror-image points of "
                                    "hub, yet a positive angle moves them other than as mirror images (panel1 towards "
                                    "N -z, panel2 towards N +z)"])
        self.assertEqual([w["code"] for w in g["warnings"]], ["mirror-axes"])

    def test_a_flipped_child_point_is_named(self):
        g, warnings, _ = self.messages("hinged_panels_flipped_child_point")
        self.assertEqual(warnings[0], "hinge1: panel1's CM is inboard of the joint, inside hub's box: check the "
                                      "sign of child_point and the offset")
        self.assertEqual([w["code"] for w in g["warnings"]], ["cm-inboard", "mirror-axes"])
        self.assertEqual(g["warnings"][0]["subject"], "hinge1")
        self.assertIsNone(g["warnings"][0]["line"])


class StabilityMap(unittest.TestCase):
    """The stability page (crossdyn stability --report): every cell drawn in its class's colour at
    its row (integrator x setting) and column (parameter value), and the findings on the page."""

    def summary(self):
        cells = []
        classes = ["accurate", "diverged", "too costly", "drift"]
        for col, value in enumerate([10.0, 1000.0]):
            for row, dt in enumerate([0.1, 0.01]):
                cell = dict(engine="kane", integrator="rk4", fixed_step=True, setting=dt,
                            setting_text="dt %g" % dt, column=col, why="because", history_error=1e-9,
                            cpu=1e-3, rhs_calls=40, steps=10, h_lambda=dt * value)
                cell["class"] = classes[2 * col + row]
                cells.append(cell)
        return {"tool": "crossdyn", "kind": "stability", "maps": [dict(
            scene="toy", file="toy.yaml", id="toy-k", page="toy-k.html", csv="toy-k.csv",
            parameter=dict(spec="hinge.stiffness", unit="N m/rad", description="the spring"),
            limits=dict(tolerance=1e-8, drift_limit=1e-6, diverged_error=10.0),
            columns=[dict(value=10.0, reference=True, reference_note="ok", lambda_max=[10.0]),
                     dict(value=1000.0, reference=True, reference_note="ok", lambda_max=[1000.0])],
            engines=["kane"], integrators=["rk4"], cells=cells,
            findings=["kane + rk4: it diverges at dt 0.1 when stiff"], notes=[])]}

    def test_cells_are_coloured_by_class_and_the_findings_are_on_the_page(self):
        from crossdyn_report import stability
        from matplotlib.colors import to_rgb
        with tempfile.TemporaryDirectory() as d:
            summary = self.summary()
            self.assertEqual(stability.report(summary, d, pages.environment(), pages.render, print), 0)
            page = open(os.path.join(d, "toy-k.html"), encoding="utf-8").read()
            self.assertIn("kane + rk4: it diverges at dt 0.1 when stiff", visible(page))
            self.assertIn('src="toy-k.png"', page)
            self.assertIn('href="toy-k.html"', open(os.path.join(d, "index.html"), encoding="utf-8").read())
            # The map's pixel colours: each class present in the image.
            import matplotlib.image as mpimg
            img = mpimg.imread(os.path.join(d, "toy-k.png"))[:, :, :3]
            for cls in ["accurate", "diverged", "too costly", "drift"]:
                rgb = np.array(to_rgb(stability.CLASS_COLOURS[cls]))
                close = np.all(np.abs(img - rgb) < 0.02, axis=2)
                self.assertGreater(close.sum(), 500, cls)


MAKE_REPORT = os.path.join(SOURCE, "reports", "make_report.py")


def run_make_report(summary, out, jobs):
    env = dict(os.environ, CROSSDYN_REPORT_JOBS=str(jobs), PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run([sys.executable, MAKE_REPORT, summary, out], env=env, capture_output=True, text=True,
                          timeout=600)


def folder_bytes(folder):
    files = {}
    for root, _, names in os.walk(folder):
        for n in names:
            path = os.path.join(root, n)
            with open(path, "rb") as f:
                files[os.path.relpath(path, folder)] = f.read()
    return files


class WorkerProcesses(unittest.TestCase):
    """The scenes' pages are drawn in worker processes (CROSSDYN_REPORT_JOBS, default one per CPU):
    the same files as one process, the same messages and exit status when something fails."""

    def test_same_files_in_one_process_and_in_workers(self):
        scenes = [os.path.join(SOURCE, "scenarios", s + ".yaml") for s in ("torque_free_axisymmetric", "dual_spin")]
        with tempfile.TemporaryDirectory() as tmp:
            base = os.path.join(tmp, "base")
            subprocess.run([CROSSDYN, "verify", "--quiet", "--no-converge", *scenes, "--report=" + base,
                            "--report-script", MAKE_REPORT], check=True, stdout=subprocess.DEVNULL, timeout=600)
            made = {}
            for jobs in (1, 2, 3):
                out = os.path.join(tmp, "jobs%d" % jobs)
                subprocess.run(["cp", "-r", base, out], check=True)
                for n in os.listdir(out):
                    if n.endswith((".html", ".png")):
                        os.unlink(os.path.join(out, n))
                r = run_make_report(os.path.join(out, "summary.json"), out, jobs)
                self.assertEqual(r.returncode, 0, r.stderr)
                made[jobs] = folder_bytes(out)
            self.assertEqual(sorted(made[1]), sorted(folder_bytes(base)))  # every page and picture
            self.assertGreater(sum(n.endswith(".png") for n in made[1]), 10)
            self.assertFalse([n for n in made[1] if ".tmp." in n])
            for jobs in (2, 3):
                self.assertEqual(sorted(made[jobs]), sorted(made[1]))
                for n in made[1]:
                    self.assertEqual(made[jobs][n], made[1][n], "%s differs with %d workers" % (n, jobs))

    def test_a_failing_scene_fails_the_same_way_in_workers(self):
        summary = summary_three_scenes()
        del summary["scenes"][1]["page"]  # the second scene's page cannot be written: KeyError
        summary["scenes"][0]["runs"][0]["data"] = "data/good/missing.csv"  # a warning, the page goes on
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "summary.json")
            with open(path, "w", encoding="utf-8") as f:
                json.dump(summary, f)
            results = {}
            for jobs in (1, 2, "x"):
                out = os.path.join(tmp, "out%s" % jobs)
                results[jobs] = run_make_report(path, out, jobs)
                self.assertFalse(os.path.exists(os.path.join(out, "index.html")), jobs)
                self.assertFalse([n for n in os.listdir(out) if ".tmp." in n], jobs)
            for jobs, r in results.items():
                self.assertEqual(r.returncode, 1, (jobs, r.stderr))
                self.assertIn("KeyError: 'page'", r.stderr, jobs)
                self.assertIn("make_report.py: cannot read", r.stderr, jobs)
                self.assertIn("missing.csv", r.stderr, jobs)
            self.assertIn("CROSSDYN_REPORT_JOBS='x' is not a number", results["x"].stderr)

    def test_sigterm_ends_the_script_and_its_workers(self):
        # crossdyn ends the script with SIGTERM when it is interrupted: no worker may go on writing.
        scenes = [os.path.join(SOURCE, "scenarios", s + ".yaml") for s in ("dual_spin", "chain5", "spear1_case1")]
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "report")
            subprocess.run([CROSSDYN, "verify", "--quiet", "--no-converge", *scenes, "--report=" + out,
                            "--report-script", MAKE_REPORT], check=True, stdout=subprocess.DEVNULL, timeout=600)
            for n in os.listdir(out):
                if n.endswith((".html", ".png")):
                    os.unlink(os.path.join(out, n))
            env = dict(os.environ, CROSSDYN_REPORT_JOBS="2", PYTHONDONTWRITEBYTECODE="1")
            p = subprocess.Popen([sys.executable, MAKE_REPORT, os.path.join(out, "summary.json"), out], env=env,
                                 stderr=subprocess.DEVNULL)
            children = "/proc/%d/task/%d/children" % (p.pid, p.pid)
            workers = []
            for _ in range(400):  # up to 20 s for the workers to start
                with open(children) as f:
                    workers = f.read().split()
                if len(workers) >= 2:
                    break
                time.sleep(0.05)
            self.assertGreaterEqual(len(workers), 2)
            p.send_signal(signal.SIGTERM)
            self.assertEqual(p.wait(timeout=20), 128 + signal.SIGTERM)
            time.sleep(0.5)
            for w in workers:
                self.assertFalse(os.path.exists("/proc/%s" % w) and open("/proc/%s/stat" % w).read().split()[2] != "Z",
                                 "worker %s outlived the script" % w)
            self.assertFalse(os.path.exists(os.path.join(out, "index.html")))
            self.assertFalse([n for n in os.listdir(out) if ".tmp." in n])


if __name__ == "__main__":
    unittest.main()
