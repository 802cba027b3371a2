"""The report's HTML pages: the data each page shows (plain Python values), rendered through the
Jinja2 templates in reports/templates/ (autoescaped; no scripts, no network)."""

import json
import os

import jinja2

from .charts import GROUP_TITLES
from .common import gfmt, sci, vec

TEMPLATES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "templates")

# What each kind of check compares, for the index's column headers and the pages' legends.
GROUP_HELP = {
    "run": "each engine ran to the end",
    "t": "runs give the same output times",
    "w": "bodies' angular velocities <body>.wx/wy/wz",
    "attitude": "bodies' attitudes (rotation angle between runs)",
    "rate": "joint rates (revolute and prismatic .rate, universal .rate1/.rate2, spherical .wx/wy/wz)",
    "angle": "joint angles (revolute .angle, universal .angle1/.angle2)",
    "position": "positions: prismatic joints', bodies' <body>.x/y/z and the system CM CMx/CMy/CMz",
    "torque": "the torque (force) a prescribed joint takes",
    "modal": "flexible bodies' modal coordinates",
    "load": "joint loads <joint>.Fx .. .Mz: force and moment of the parent on the child",
    "H": "angular momentum H, its vector Hx/Hy/Hz and the external moment Mx/My/Mz",
    "E": "energy E and the power P of the non-conservative loads",
    "H.drift": "each engine's drift of H from H(0) where H is conserved, else its balance "
               "H(t) - H(0) - integral of M; and dH/dt against M at every output time",
    "E.drift": "each engine's drift of E from E(0) where E is conserved, else its balance "
               "E(t) - E(0) - integral of P; and dE/dt against P at every output time",
    "J.drift": "on an orbit, each engine's drift of the Jacobi integral J from J(0) (E changes "
               "there as the gravity-gradient potential turns with the orbit)",
    "extra": "extra columns named in the scene's tolerances",
}
# Why a scene has no check of a kind: the feature does not exist in it.
GROUP_ABSENT = {
    "rate": "no joints with rates",
    "angle": "no revolute or universal joints",
    "position": "no prismatic joints",
    "torque": "no prescribed joints",
    "modal": "no flexible bodies",
    "attitude": "no attitudes compared",
    "extra": "no extra columns asked for",
    "E.drift": "E not checked",
    "H.drift": "H not checked",
    "load": "no joints but the free one",
    "J.drift": "not on an orbit",
}
# The index shows a conserved quantity's drift and a balanced one's balance in one column (a scene
# has one or the other): the table stays narrow enough to read without scrolling.
def environment_text(e):
    """The scene's environment in one sentence (docs/environment.md), or "" without one."""
    kind = e.get("kind", "none")
    if kind == "uniform":
        g = e.get("g_N", [0, 0, 0])
        return "Uniform gravity g = (%s) m/s^2 in N, on every mass." % ", ".join(gfmt(x) for x in g)
    if kind == "orbit":
        import math
        n = e.get("mean_motion", 0.0)
        return ("A central body (mu = %s m^3/s^2) and the system's CM on a circular orbit of radius %s km "
                "(inclination %s deg, raan %s deg, argument of latitude %s deg at t = 0): mean motion "
                "n = %s rad/s, orbit period %s s. The gravity gradient to second order about the "
                "system's CM; attitudes relative to the orbit frame (LVLH) and the Jacobi integral J in "
                "the output." % (gfmt(e.get("mu")), gfmt(e.get("radius_m", 0) / 1e3),
                                 gfmt(math.degrees(e.get("inclination_rad", 0))), gfmt(math.degrees(e.get("raan_rad", 0))),
                                 gfmt(math.degrees(e.get("latitude0_rad", 0))), gfmt(n),
                                 gfmt(2 * math.pi / n) if n > 0 else "-"))
    return ""


MERGED_COLUMNS = {"H.balance": "H.drift", "E.balance": "E.drift"}
COLUMN_TITLES = {"H.drift": "H drift or balance", "E.drift": "E drift or balance",
                 "J.drift": "Jacobi integral J drift"}

PASS_RULE = ("pass when  max over the run of |a(t) - b(t)|  <=  atol + rtol * max over the run of |b(t)|")


def environment():
    return jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                              undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                              keep_trailing_newline=True)


def pair(c):
    return c["a"] + (" vs " + c["b"] if c.get("b") else "")


def check_line(c):
    """One line naming a failed check and its numbers (as harness/report.cpp describe_failure)."""
    if c["group"] == "run":
        return "%s: run failed at t = %s s: %s" % (pair(c), gfmt(c.get("time")), c.get("note", ""))
    line = ("%s, %s: max error %s at t = %s s > bound %s (atol %s + rtol %s * %s), normalised %s"
            % (c["quantity"], pair(c), sci(c.get("error"), 4), gfmt(c.get("time")), sci(c.get("bound"), 4),
               sci(c.get("atol"), 2), sci(c.get("rtol"), 2), sci(c.get("scale"), 4), sci(c.get("normalised"))))
    if c.get("first_exceeded") is not None:
        line += ", first over at t = %s s" % gfmt(c["first_exceeded"])
    if c.get("note"):
        line += " (%s)" % c["note"]
    return line


def status_counts(checks):
    counts = {"PASS": 0, "FAIL": 0, "EXCLUDED": 0, "SKIPPED": 0}
    for c in checks:
        counts[c["status"]] = counts.get(c["status"], 0) + 1
    return counts


def scene_result(s):
    if s.get("input_error"):
        return "BAD INPUT"
    return "PASS" if s.get("passed") else "FAIL"


# ----------------------------------------------------------------------------------------------
# Index


def index_context(summary):
    scenes = summary.get("scenes", [])
    order = summary.get("group_order", [])
    shown = lambda g: MERGED_COLUMNS.get(g, g)  # noqa: E731
    present = [g for g in order if g not in MERGED_COLUMNS and
               any(shown(x["group"]) == g for s in scenes for x in s.get("groups", []))]
    rows = []
    failed_checks = []
    warned = []  # every scene warning: (scene, page, message, code)
    for s in scenes:
        by = {shown(x["group"]): x for x in s.get("groups", [])}
        cells = []
        for g in present:
            x = by.get(g)
            if s.get("input_error"):
                cells.append(dict(kind="none", text="", detail=""))
            elif not x:
                cells.append(dict(kind="absent", text="n/a", detail=GROUP_ABSENT.get(g, "no such checks")))
            elif g == "run":
                ok = x["checks"] - x["failed"] - x["skipped"]
                text = ("%d of %d failed" % (x["failed"], x["checks"])) if x["failed"] else "%d ran" % ok
                if x["skipped"]:
                    text += ", %d skipped" % x["skipped"]
                cells.append(dict(kind=x["status"], text=text, detail=""))
            elif x["status"] in ("PASS", "FAIL"):
                # The colour says pass or fail; a failing cell also says it in words.
                text = sci(x["worst"], 2) if x["status"] == "PASS" else "FAIL %s" % sci(x["worst"], 2)
                cells.append(dict(kind=x["status"], text=text,
                                  detail=x["worst_check"] + (" (%d of %d failed)" % (x["failed"], x["checks"])
                                                             if x["failed"] else "")))
            else:  # excluded or skipped: the reason the scene (or the run) gives
                why = next((c.get("note", "") for c in s.get("checks", [])
                            if shown(c.get("group", "")) == g and c.get("status") == x["status"]), "")
                cells.append(dict(kind=x["status"], text=x["status"].lower(), detail=why))
        for c in s.get("checks", []):
            if c["status"] == "FAIL":
                failed_checks.append(dict(scene=s.get("scene"), page=s["page"], line=check_line(c)))
        rows.append(dict(scene=s.get("scene"), page=s["page"], cells=cells, result=scene_result(s),
                         input_error=s.get("input_error", ""), warnings=len(s.get("warnings", []))))
        for w in s.get("warnings", []):
            warned.append(dict(scene=s.get("scene"), page=s["page"], message=w.get("message", ""),
                               code=w.get("code", "")))
    counts = summary.get("counts", {})
    n = counts.get("scenes", len(scenes))
    unreadable = counts.get("scenes_unreadable", 0)
    failed = counts.get("scenes_failed", 0)
    all_checks = [c for s in scenes for c in s.get("checks", [])]
    return dict(
        title="crossdyn verification report",
        verdict="PASS" if summary.get("passed") else "FAIL",
        scenes_total=n, scenes_passed=n - failed - unreadable, scenes_failed=failed,
        scenes_unreadable=unreadable, checks=status_counts(all_checks), checks_total=len(all_checks),
        columns=[dict(group=g, title=COLUMN_TITLES.get(g, GROUP_TITLES.get(g, g)), help=GROUP_HELP.get(g, ""))
                 for g in present],
        rows=rows, failed_checks=failed_checks, warned=warned,
        unreadable=[r for r in rows if r["input_error"]],
        pass_rule=PASS_RULE, summary=summary.get("pass_rule", {}))


# ----------------------------------------------------------------------------------------------
# Scene page


def _inertia_text(inertia):
    if all(abs(inertia[i][j]) == 0 for i in range(3) for j in range(3) if i != j):
        return "diag" + vec([inertia[i][i] for i in range(3)])
    return json.dumps(inertia)


def scene_tables(system):
    """Bodies and joints tables, with a column only where some row has something in it."""
    bodies = system.get("bodies", [])
    has_modes = any(b.get("modes") for b in bodies)
    has_torque = any(b.get("torque_N_m") for b in bodies)
    body_head = ["body", "mass (kg)", "inertia about CM, body axes (kg m^2)"]
    if has_modes:
        body_head.append("flexible modes")
    if has_torque:
        body_head.append("external torque (N m), from time t (s)")
    body_rows = []
    for b in bodies:
        row = [b["name"], gfmt(b["mass_kg"]), _inertia_text(b["inertia_kg_m2"])]
        if has_modes:
            row.append(", ".join(b.get("modes", [])) or "rigid")
        if has_torque:
            row.append(json.dumps(b["torque_N_m"]) + " (" + b["torque_frame"] + " frame)"
                       if b.get("torque_N_m") else "none")
        body_rows.append(row)
    joint_rows = []
    any_loads = False
    for j in system.get("joints", []):
        ini = j.get("initial", {})
        if j["type"] == "free":
            geometry = "base body; parent is the inertial frame N"
            initial = "w_NB_B = %s rad/s, q_NB = %s" % (vec(ini.get("w_NB_B_rad_s", [])), vec(ini.get("q_NB", [])))
            if any(ini.get("p_NoBo_N_m", [0, 0, 0])):
                initial += ", p_NoBo_N = %s m" % vec(ini["p_NoBo_N_m"])
        else:
            geometry = "parent point %s m, child point %s m" % (vec(j["parent_point_m"]), vec(j["child_point_m"]))
            if "axis" in j:
                geometry += ", axis %s (parent frame)" % vec(j["axis"])
            if "orientation_offset_q" in j:
                geometry += ", offset q %s" % vec(j["orientation_offset_q"])
            if "axes" in j:
                geometry += ", axes %s, %s (parent frame at zero angles)" % (vec(j["axes"][0]), vec(j["axes"][1]))
            if j["type"] == "revolute":
                initial = "angle %s rad, rate %s rad/s" % (gfmt(ini.get("angle_rad")), gfmt(ini.get("rate_rad_s")))
            elif j["type"] == "prismatic":
                initial = "position %s m, rate %s m/s" % (gfmt(ini.get("position_m")), gfmt(ini.get("rate_m_s")))
            elif j["type"] == "universal":
                initial = "angles %s rad, rates %s rad/s" % (vec(ini.get("angles_rad", [])), vec(ini.get("rates_rad_s", [])))
            elif j["type"] == "spherical":
                initial = "q_J %s, w_PC_C %s rad/s" % (vec(ini.get("q_J", [])), vec(ini.get("w_PC_C_rad_s", [])))
            else:
                initial = "-"
        loads = []
        for key, label in (("stiffness_N_m_rad", "stiffness %s N m/rad"), ("damping_N_m_s_rad", "damping %s N m s/rad"),
                           ("neutral_angle_rad", "neutral angle %s rad"), ("stiffness_N_m", "stiffness %s N/m"),
                           ("damping_N_s_m", "damping %s N s/m"), ("neutral_position_m", "neutral position %s m")):
            if key in j:  # a universal joint's are pairs, [axis 1, axis 2]
                loads.append(label % (vec(j[key]) if isinstance(j[key], list) else gfmt(j[key])))
        for key, unit in (("motor_N_m", "N m"), ("motor_N", "N")):
            if key in j:
                loads.append("motor " + ", ".join("%s %s from t = %s s" % (json.dumps(m["value"]), unit, gfmt(m["from_t"]))
                                                  for m in j[key]))
        any_loads = any_loads or bool(loads)
        joint_rows.append([j["name"], j["type"], "%s -> %s" % (j["parent"], j["child"]), geometry, initial,
                           "; ".join(loads)])
    joint_head = ["joint", "type", "parent -> child", "geometry", "initial state", "loads"]
    if not any_loads:
        joint_head = joint_head[:-1]
        joint_rows = [r[:-1] for r in joint_rows]
    return dict(body_head=body_head, body_rows=body_rows, joint_head=joint_head, joint_rows=joint_rows)


def run_rows(scene):
    rows = []
    for r in scene.get("runs", []):
        failure = r.get("failure")
        note = r.get("note", "")
        analytic = r["engine"] == "analytic"
        if analytic:
            note = "closed-form torque-free solution (Jacobi elliptic functions)"
        if failure:
            note += " (failed at t = %s s)" % gfmt(failure["time"])
        rows.append(dict(label=r["label"], state=r["state"], rows=r["rows"],
                         rhs="-" if analytic else r["rhs_calls"], steps="-" if analytic else r["steps"],
                         wall="-" if analytic else gfmt(r["wall_seconds"], 3), note=note,
                         csv=r.get("data", ""),
                         cls={"ok": "", "failed": "FAIL", "skipped": "SKIPPED"}.get(r["state"], "")))
    return rows


def check_rows(scene):
    order = {"FAIL": 0, "PASS": 1, "EXCLUDED": 2, "SKIPPED": 3}
    rows = []
    for c in sorted(scene.get("checks", []), key=lambda c: order.get(c["status"], 9)):
        numbers = c["status"] in ("PASS", "FAIL") and c["group"] != "run"
        dash = "-"
        rows.append(dict(
            status=c["status"], quantity=c["quantity"], pair=pair(c),
            error=sci(c["error"]) if numbers else dash,
            time=gfmt(c["time"]) if numbers or (c["group"] == "run" and c["status"] == "FAIL") else dash,
            first=gfmt(c["first_exceeded"]) if c.get("first_exceeded") is not None else dash,
            atol=sci(c["atol"], 2) if numbers else dash, rtol=sci(c["rtol"], 2) if numbers else dash,
            scale=sci(c["scale"]) if numbers else dash, bound=sci(c["bound"]) if numbers else dash,
            normalised=sci(c["normalised"]) if numbers else dash,
            note=c["note"] or ("tolerance '%s'" % c["tolerance_key"]
                               if c["tolerance_key"] not in ("default", "-") else "")))
    return rows


def converge_context(scene, chart):
    """The model-size section: `crossdyn converge`'s table (verify runs it on flexible scenes)."""
    conv = scene.get("converge")
    note = scene.get("converge_note", "")
    if not conv:
        return dict(rows=[], chart=None, smallest="", engine="", note=note) if note else None
    rows = []
    for m in conv.get("models", []):
        worst = m.get("worst_relative", m.get("worst_normalised"))
        rows.append(dict(label=m["label"], modes=m["modes"],
                         change="reference" if m.get("full") else sci(worst if worst is not None else float("inf")),
                         where="" if m.get("full") else m.get("worst_quantity", ""),
                         verdict="" if m.get("full") else ("within" if m["passed"] else "changes"),
                         cls="" if m.get("full") else ("pass" if m["passed"] else "fail")))
    return dict(rows=rows, chart=chart, smallest=conv.get("smallest", ""), engine=conv.get("engine", ""),
                accuracy=sci(conv.get("accuracy", 1e-3)),
                note=note, notes=conv.get("notes", []))


def scene_context(scene, pictures, charts, motion_note, converge=None):
    system = scene.get("system", {})
    settings = scene.get("settings", {})
    run = system.get("run", {})
    comp = system.get("compare", {})
    tolerances = [dict(key="default", atol=sci(comp.get("default", {}).get("atol")),
                       rtol=sci(comp.get("default", {}).get("rtol")), note="")]
    for t in comp.get("tolerances", []):
        tolerances.append(dict(key=t["quantity"], atol=sci(t["atol"]), rtol=sci(t["rtol"]), note=""))
    for x in comp.get("excluded", []):
        tolerances.append(dict(key=x["quantity"], atol="-", rtol="-", note="excluded: " + x["reason"]))
    checks = scene.get("checks", [])
    return dict(
        title="crossdyn: " + str(scene.get("scene", scene["id"])),
        scene=scene.get("scene", scene["id"]), path=scene.get("path", ""), result=scene_result(scene),
        input_error=scene.get("input_error", ""),
        counts=status_counts(checks), checks_total=len(checks),
        failed=[check_line(c) for c in checks if c["status"] == "FAIL"],
        description=system.get("description", ""), source=system.get("source", ""),
        pictures=pictures, motion_note=motion_note,
        warnings=[dict(message=w.get("message", ""), code=w.get("code", "")) for w in scene.get("warnings", [])],
        tables=scene_tables(system) if system else None,
        run_text=("0 to %s s, output every %s s, integrator %s (rtol %s, atol %s). Total linear momentum %s."
                  % (gfmt(settings.get("duration_s", run.get("duration_s"))),
                     gfmt(settings.get("output_step_s", run.get("output_step_s"))),
                     settings.get("integrator", run.get("integrator")), gfmt(settings.get("rtol")),
                     gfmt(settings.get("atol")), "zero" if system.get("zero_linear_momentum") else "as given")),
        analytic=system.get("analytic", ""), environment_text=environment_text(system.get("environment", {})),
        tolerances=tolerances, runs=run_rows(scene), charts=charts, checks=check_rows(scene),
        notes=scene.get("notes", []), pass_rule=PASS_RULE, converge=converge,
        groups=[dict(title=GROUP_TITLES.get(g["group"], g["group"]), help=GROUP_HELP.get(g["group"], ""))
                for g in scene.get("groups", [])])


def render(env, template, context):
    return env.get_template(template).render(**context)


# ----------------------------------------------------------------------------------------------
# `crossdyn study`: speed against accuracy (study.json, "kind": "study")


def _ms(seconds):
    return "n/a" if seconds is None else "%.3g" % (1e3 * seconds)


def study_scene_context(summary, scene, chart):
    rows = []
    for r in scene.get("rows", []):
        rows.append(dict(
            engine=r["engine"], integrator=r["integrator"], setting=r["setting"], ok=r["ok"],
            cpu=_ms(r.get("cpu_median")) if r["ok"] else "failed",
            spread=("%s to %s" % (_ms(r.get("cpu_min")), _ms(r.get("cpu_max")))) if r["ok"] else "",
            repeats=r.get("repeats", 0), rhs=r["rhs_calls"], steps=r["steps"], rejected=r["rejected"],
            end=sci(r.get("end_error"), 2) if r["ok"] else "-",
            end_q=r.get("end_quantity", ""),
            history=sci(r.get("history_error"), 2) if r["ok"] else "-",
            history_q=r.get("history_quantity", ""),
            front=("end" if r.get("front_end") else "") + (" history" if r.get("front_history") else ""),
            failure=r.get("failure", "")))
    ref = scene.get("reference", {})
    return dict(
        title="crossdyn study: " + scene["scene"], scene=scene["scene"], file=scene.get("file", ""),
        duration=gfmt(scene.get("duration")), output_step=gfmt(scene.get("output_step")),
        reference=ref.get("description", ""), reference_kind=ref.get("kind", ""),
        recommendations=[x["text"] for x in scene.get("recommendations", [])],
        chart=chart, csv=scene.get("csv", ""), rows=rows, notes=scene.get("notes", []),
        timing=summary.get("timing", ""), error_metric=summary.get("error_metric", ""),
        csv_header=summary.get("csv_header", "").strip())


def scaling_context(summary, chart, cond_chart=None):
    sc = summary.get("scaling") or {}
    lines = sc.get("lines", [])
    table, cond_table = [], []
    for k, n in enumerate(sc.get("links", [])):
        cells, cond_cells = [], []
        for line in lines:
            p = line["points"][k] if k < len(line["points"]) else None
            cells.append("%.4g" % (1e6 * p["seconds_per_call"]) if p and p.get("seconds_per_call") else "-")
            cond_cells.append("%.3g" % p["condition"] if p and p.get("condition") is not None else "-")
            cond_cells.append("%.2g" % p["accel_deviation"] if p and p.get("accel_deviation") is not None else "-")
        table.append(dict(links=n, cells=cells))
        cond_table.append(dict(links=n, cells=cond_cells))
    fmt = lambda v: ("%.2f" % v) if v is not None else "-"
    return dict(title="crossdyn study: right-hand-side cost against chain length", chart=chart,
                engines=[x["engine"] for x in lines],
                exponents=[fmt(x.get("exponent")) for x in lines],
                table=table, csv=sc.get("csv", ""), budget=gfmt(sc.get("budget")),
                cond_chart=cond_chart, cond_table=cond_table,
                cond_exponents=[fmt(x.get("condition_exponent")) for x in lines],
                systems=[dict(engine=x["engine"], what=x["system"]) for x in lines if x.get("system")])


def study_index_context(summary):
    scenes = []
    for s in summary.get("scenes", []):
        ok = [r for r in s.get("rows", []) if r["ok"]]
        scenes.append(dict(scene=s["scene"], page=s["page"], configurations=len(s.get("rows", [])),
                           failed=len(s.get("rows", [])) - len(ok),
                           reference=s.get("reference", {}).get("kind", ""),
                           recommendations=[x["text"] for x in s.get("recommendations", [])]))
    sc = summary.get("scaling")
    return dict(title="crossdyn: speed against accuracy", scenes=scenes,
                scaling=dict(page=sc.get("page", "scaling.html"),
                             exponents=[dict(engine=x["engine"],
                                             exponent=("%.2f" % x["exponent"]) if x.get("exponent") is not None else "-")
                                        for x in sc.get("lines", [])]) if sc else None,
                timing=summary.get("timing", ""), error_metric=summary.get("error_metric", ""))
