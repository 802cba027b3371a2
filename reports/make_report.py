#!/usr/bin/python3
"""Static HTML report of a `crossdyn verify` run.

    /usr/bin/python3 reports/make_report.py SUMMARY.json OUT_DIR

Reads the JSON summary that `crossdyn verify --report DIR` writes (DIR/summary.json) and the runs'
CSV files it names (DIR/data/<scene>/<run>.csv), and writes into OUT_DIR:

    index.html             every scene x check group: worst normalised error, PASS/FAIL
    <scene>.html           one page per scene: data and assumptions, runs, charts, every check
    <scene>-*.png          the charts, next to the pages

The pages work offline: no scripts, no web fonts, images are local PNG files. Every file is
written to a temporary name and renamed into place, so a reader never sees a half-written page.
Charts use matplotlib's Agg backend (Debian python3-matplotlib; run with /usr/bin/python3).
In the JSON summary, null stands for a value that is not a finite number (NaN or infinity).
"""

import html
import io
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
import numpy as np  # noqa: E402

DPI = 96
TINY = 1e-17  # floor for log-scale plots of differences that are exactly zero

# One look per run, the same on every page: the analytic solution is a thick light line under the
# engines; engines differ in colour and dash so that curves lying on top of each other stay visible.
STYLES = {
    "analytic": dict(color="0.55", linestyle="-", linewidth=4.0, alpha=0.8),
    "kane": dict(color="tab:blue", linestyle="-", linewidth=2.2),
    "lagrange": dict(color="tab:orange", linestyle="--", linewidth=1.8),
    "newton-euler": dict(color="tab:green", linestyle=":", linewidth=2.0),
}
EXTRA_COLOURS = ["tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan"]

GROUP_TITLES = {
    "run": "engine runs",
    "t": "output times",
    "w": "angular velocities",
    "attitude": "attitudes",
    "rate": "joint rates",
    "angle": "joint angles",
    "modal": "modal coordinates",
    "H": "angular momentum H",
    "E": "energy E",
    "H.drift": "drift of H",
    "E.drift": "drift of E",
    "extra": "extra columns",
}

CSS = """
body { font-family: sans-serif; max-width: 1100px; margin: 1.5em auto; padding: 0 1em;
       color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
td.num { text-align: right; font-family: monospace; }
.PASS { background: #dff0d8; } .FAIL { background: #f2dede; font-weight: bold; }
.EXCLUDED, .SKIPPED { background: #f5f5f5; color: #666; }
.badge { padding: 0.1em 0.5em; border-radius: 0.3em; }
figure { margin: 1.2em 0; } figcaption { font-size: 0.9em; color: #444; max-width: 60em; }
img { max-width: 100%; border: 1px solid #ddd; }
code, pre { background: #f7f7f7; } pre { padding: 0.5em; white-space: pre-wrap; }
.note { color: #555; font-size: 0.9em; }
"""


# ----------------------------------------------------------------------------------------------
# Small helpers


def write_atomic(path, data):
    """Writes bytes or text to path through a temporary file and a rename."""
    tmp = "%s.tmp.%d" % (path, os.getpid())
    mode = "wb" if isinstance(data, bytes) else "w"
    with open(tmp, mode, **({} if mode == "wb" else {"encoding": "utf-8"})) as f:
        f.write(data)
    os.replace(tmp, path)


def save_figure(fig, path):
    """Saves a chart as a 256-colour PNG (a third of the size of a full-colour one, which matters
    for the committed example) through a temporary file and a rename."""
    tmp = "%s.tmp.%d" % (path, os.getpid())
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    plt.close(fig)
    try:
        from PIL import Image  # Pillow comes with Debian's matplotlib

        buf.seek(0)
        image = Image.open(buf).convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        out = io.BytesIO()
        image.save(out, format="PNG", optimize=True)
        data = out.getvalue()
    except Exception:  # no Pillow or an old one: keep matplotlib's PNG
        data = buf.getvalue()
    write_atomic(path, data)


def esc(x):
    return html.escape("" if x is None else str(x))


def sci(v, digits=3):
    if v is None:
        return "n/a"
    if v == 0:
        return "0"
    return "%.*e" % (digits - 1, v)


def gfmt(v, digits=6):
    return "n/a" if v is None else "%.*g" % (digits, v)


def style_of(label, index):
    if label in STYLES:
        return dict(STYLES[label])
    base = label.split("*")[0]
    colour = EXTRA_COLOURS[index % len(EXTRA_COLOURS)]
    style = dict(STYLES.get(base, {}), color=colour, linestyle="-.", linewidth=1.6)
    return style


def load_csv(path):
    """Returns (columns, data) with data shaped rows x columns, or None when unreadable."""
    try:
        with open(path, encoding="utf-8") as f:
            header = f.readline().strip().split(",")
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError) as e:
        print("make_report.py: cannot read %s: %s" % (path, e), file=sys.stderr)
        return None
    if data.size == 0:
        data = np.zeros((0, len(header)))
    return header, data


class Run:
    """One run of a scene with its samples."""

    def __init__(self, info, out_dir, index):
        self.label = info["label"]
        self.info = info
        self.style = style_of(self.label, index)
        self.columns, self.data = [], np.zeros((0, 0))
        if info.get("data"):
            loaded = load_csv(os.path.join(out_dir, info["data"]))
            if loaded:
                self.columns, self.data = loaded

    def has(self, name):
        return name in self.columns and self.data.shape[0] > 0

    def col(self, name):
        return self.data[:, self.columns.index(name)]

    @property
    def t(self):
        return self.col("t")


# ----------------------------------------------------------------------------------------------
# Charts. Each returns (file name, caption) or None when the scene has nothing to show.


def rad_axis(ax, unit):
    """A secondary axis in degrees for an axis in rad or rad/s."""
    ax.secondary_yaxis("right", functions=(np.degrees, np.radians)).set_ylabel(
        unit.replace("rad", "deg"))


def plot_lines(ax, runs, column, label_prefix=""):
    drawn = False
    for r in runs:
        if r.has(column):
            ax.plot(r.t, r.col(column), label=label_prefix + r.label, **r.style)
            drawn = True
    return drawn


def paper_figures(scene):
    """The reference paper's figure numbers for the SPEAR-1 scenes (spin, deployment, H)."""
    name = scene.get("scene", "")
    if name.startswith("spear1_case1"):
        return ("4", "5", "6")
    if name.startswith("spear1_case2"):
        return ("7", "8", "9")
    return None


def chart_base_w(scene, runs, out_dir, sid):
    system = scene.get("system", {})
    base = system.get("joints", [{}])[0].get("child") if system.get("joints") else None
    if not base or not any(r.has(base + ".wx") for r in runs):
        return None
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    # A component that stays at rounding-error level is drawn on a span of at least 1e-3 of the
    # largest component, so it reads as the flat zero it is.
    peak = max([float(np.max(np.abs(r.col("%s.w%s" % (base, c))))) for r in runs
                for c in ("x", "y", "z") if r.has("%s.w%s" % (base, c))] + [1e-12])
    for ax, comp in zip(axes, ("x", "y", "z")):
        plot_lines(ax, runs, "%s.w%s" % (base, comp))
        values = [r.col("%s.w%s" % (base, comp)) for r in runs if r.has("%s.w%s" % (base, comp))]
        if values:
            v = np.concatenate(values)
            lo, hi = float(np.min(v)), float(np.max(v))
            if hi - lo < 1e-3 * peak:
                mid = 0.5 * (lo + hi)
                ax.set_ylim(mid - 1e-3 * peak, mid + 1e-3 * peak)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_ylabel("%s.w%s (rad/s)" % (base, comp))
        rad_axis(ax, "rad/s")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time t (s)")
    figs = paper_figures(scene)
    fig.suptitle("Angular velocity of the base body '%s' in N, components in its own body axes%s"
                 % (base, "\n(%s.wx is the spin rate of the paper's Fig. %s)" % (base, figs[0]) if figs else ""))
    fig.tight_layout()
    name = "%s-base-w.png" % sid
    save_figure(fig, os.path.join(out_dir, name))
    return name, ("Inertial angular velocity of the base body %s, resolved in its body frame "
                  "(rad/s; degrees per second on the right axis), every run overlaid. Curves that "
                  "agree lie on top of each other; the dashes let each stay visible." % base)


def chart_joints(scene, runs, out_dir, sid):
    joints = [j for j in scene.get("system", {}).get("joints", []) if j["type"] in ("revolute", "spherical")]
    if not joints:
        return None
    revolute = [j for j in joints if j["type"] == "revolute"]
    spherical = [j for j in joints if j["type"] == "spherical"]
    panels = (2 if revolute else 0) + (1 if spherical else 0)
    fig, axes = plt.subplots(panels, 1, figsize=(9, 2.9 * panels + 0.8), sharex=True, squeeze=False)
    axes = axes[:, 0]
    k = 0
    markers = ["", "o", "s", "^", "v", "D"]
    if revolute:
        for kind, unit, ax in (("rate", "rad/s", axes[0]), ("angle", "rad", axes[1])):
            for ji, j in enumerate(revolute):
                for r in runs:
                    if r.has(j["name"] + "." + kind):
                        st = dict(r.style)
                        ax.plot(r.t, r.col(j["name"] + "." + kind),
                                marker=markers[ji % len(markers)], markevery=max(1, len(r.t) // 12),
                                markersize=4, label="%s (%s)" % (j["name"], r.label), **st)
            ax.set_ylabel("joint %s (%s)" % (kind, unit))
            rad_axis(ax, unit)
            ax.grid(True, alpha=0.3)
            ax.legend(loc="best", fontsize="x-small", ncol=2)
        k = 2
    if spherical:
        ax = axes[k]
        for ji, j in enumerate(spherical):
            cols = [j["name"] + c for c in (".wx", ".wy", ".wz")]
            for r in runs:
                if all(r.has(c) for c in cols):
                    mag = np.sqrt(sum(r.col(c) ** 2 for c in cols))
                    ax.plot(r.t, mag, marker=markers[ji % len(markers)],
                            markevery=max(1, len(r.t) // 12), markersize=4,
                            label="%s (%s)" % (j["name"], r.label), **r.style)
        ax.set_ylabel("|w_PC| of spherical joints (rad/s)")
        rad_axis(ax, "rad/s")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="x-small", ncol=2)
    axes[-1].set_xlabel("time t (s)")
    figs = paper_figures(scene)
    fig.suptitle("Joint motion: rate and angle of each hinge (child body relative to its parent)%s"
                 % ("\n(hinge1.rate and hinge2.rate are the deployment rates of the paper's Fig. %s)" % figs[1]
                    if figs else ""))
    fig.tight_layout()
    name = "%s-joints.png" % sid
    save_figure(fig, os.path.join(out_dir, name))
    caption = ("Revolute joints: angular rate (rad/s) and angle (rad) of each child body about its "
               "hinge axis, relative to its parent. " if revolute else "")
    if spherical:
        caption += ("Spherical joints: magnitude of the angular velocity of the child relative to "
                    "the parent (rad/s). ")
    return name, caption + "Every run overlaid; marker shape tells the joints apart."


def chart_modal(scene, runs, out_dir, sid):
    cols = []
    for b in scene.get("system", {}).get("bodies", []):
        for m in b.get("modes", []):
            cols.append(b["name"] + "." + m)
    if not cols:
        return None
    fig, ax = plt.subplots(figsize=(9, 4.2))
    for c in cols:
        plot_lines(ax, runs, c, label_prefix=c + " ")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("modal coordinate (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="x-small", ncol=2)
    ax.set_title("Elastic deformation: modal coordinates of the flexible bodies")
    fig.tight_layout()
    name = "%s-modal.png" % sid
    save_figure(fig, os.path.join(out_dir, name))
    return name, ("Modal coordinates (m, in the scene's mode normalisation) of each flexible body, "
                  "every run overlaid.")


def padded_limits(values):
    lo, hi = float(np.min(values)), float(np.max(values))
    mid = 0.5 * (lo + hi)
    pad = max(0.08 * (hi - lo), 1e-3 * abs(mid), 1e-12)
    return mid - max(pad, 0.5 * (hi - lo) + pad), mid + max(pad, 0.5 * (hi - lo) + pad)


def chart_H_E(scene, runs, out_dir, sid):
    if not any(r.has("H") for r in runs):
        return None
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.2), sharex=True)
    for ax, x, unit, what in ((axes[0], "H", "kg m^2/s", "angular momentum about the system CM"),
                              (axes[1], "E", "J", "mechanical energy (kinetic + elastic)")):
        values = [r.col(x) for r in runs if r.has(x)]
        plot_lines(ax, runs, x)
        if values:
            ax.set_ylim(*padded_limits(np.concatenate(values)))
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_ylabel("%s (%s)" % (x, unit))
        ax.set_title("%s: %s" % (x, what), fontsize="medium")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time t (s)")
    figs = paper_figures(scene)
    fig.suptitle("Magnitude of the total angular momentum H and total energy E against time%s"
                 % ("\n(H is the quantity of the paper's Fig. %s)" % figs[2] if figs else ""))
    fig.tight_layout()
    name = "%s-H-E.png" % sid
    save_figure(fig, os.path.join(out_dir, name))
    return name, ("H (kg m^2/s) and E (J) of every run. The vertical range is at least 0.1 % of "
                  "the value, so a conserved quantity shows as a flat line; its drift is in the "
                  "drift chart below on a log scale.")


def attitude_angle(qa, qb):
    """Rotation angle (rad) between two attitudes given as rows of (w, x, y, z); q and -q agree.

    d = conj(qa) * qb; angle = 2 atan2(|vec d|, |w d|), accurate near zero where arccos of the dot
    product is not (the same formula as core/rotation.cpp angle_between)."""
    qa = qa / np.linalg.norm(qa, axis=1)[:, None]
    qb = qb / np.linalg.norm(qb, axis=1)[:, None]
    aw, av = qa[:, 0], -qa[:, 1:]
    bw, bv = qb[:, 0], qb[:, 1:]
    dw = aw * bw - np.sum(av * bv, axis=1)
    dv = aw[:, None] * bv + bw[:, None] * av + np.cross(av, bv)
    return 2.0 * np.arctan2(np.linalg.norm(dv, axis=1), np.abs(dw))


def chart_differences(scene, runs, out_dir, sid):
    by_label = {r.label: r for r in runs}
    pairs = []
    for c in scene.get("checks", []):
        if c["b"] and c["group"] not in ("run", "t") and (c["a"], c["b"]) not in pairs:
            pairs.append((c["a"], c["b"]))
    pairs = [p for p in pairs if by_label.get(p[0]) and by_label.get(p[1])
             and by_label[p[0]].data.shape[0] and by_label[p[1]].data.shape[0]]
    if not pairs:
        return None
    groups = [g for g in scene.get("group_order", []) if g in ("w", "attitude", "rate", "angle", "modal", "H", "E", "extra")]
    if not groups:
        groups = ["w", "attitude", "rate", "angle", "modal", "H", "E", "extra"]
    colours = dict(zip(groups, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    n = len(pairs)
    cols = 1 if n == 1 else 2
    rows_ = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows_, cols, figsize=(9 if cols == 1 else 12, 3.6 * rows_ + 1.0),
                             squeeze=False)
    for ax, (a, b) in zip(axes.flat, pairs):
        A, B = by_label[a], by_label[b]
        m = min(A.data.shape[0], B.data.shape[0])
        t = A.t[:m]
        worst = {}
        for c in scene["checks"]:
            if c["a"] != a or c["b"] != b or c["status"] not in ("PASS", "FAIL") or not c["bound"]:
                continue
            q = c["quantity"]
            if c["group"] == "attitude":
                body = q[: -len(".attitude")]
                qc = [body + s for s in (".qw", ".qx", ".qy", ".qz")]
                if not all(A.has(x) and B.has(x) for x in qc):
                    continue
                err = attitude_angle(np.column_stack([A.col(x)[:m] for x in qc]),
                                     np.column_stack([B.col(x)[:m] for x in qc]))
            else:
                if not (A.has(q) and B.has(q)):
                    continue
                err = np.abs(A.col(q)[:m] - B.col(q)[:m])
            norm = err / c["bound"]
            g = c["group"]
            worst[g] = norm if g not in worst else np.maximum(worst[g], norm)
        for g in groups:
            if g in worst:
                ax.semilogy(t, np.maximum(worst[g], TINY), color=colours[g], linewidth=1.4,
                            label=GROUP_TITLES.get(g, g))
        ax.axhline(1.0, color="red", linestyle="--", linewidth=1.2, label="tolerance (= 1)")
        ax.set_title("%s compared with %s" % (a, b), fontsize="medium")
        ax.set_xlabel("time t (s)")
        ax.set_ylabel("|a - b| / (atol + rtol max|b|)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="lower right", fontsize="x-small", ncol=2)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    fig.suptitle("Pairwise differences between runs, as a fraction of the tolerance (log scale)\n"
                 "each line: the largest over the quantities of that kind; above the red line fails")
    fig.tight_layout()
    name = "%s-differences.png" % sid
    save_figure(fig, os.path.join(out_dir, name))
    return name, ("For every pair of runs (a compared with the reference b) and every kind of "
                  "quantity, the largest normalised difference |a(t) - b(t)| / (atol + rtol "
                  "max|b|) at each output time; attitudes use the rotation angle between the two "
                  "attitudes. A check passes when its curve stays at or below 1 (red dashed line) "
                  "for the whole run. Exact agreement is drawn at 1e-17.")


def chart_drift(scene, runs, out_dir, sid):
    engines = [r for r in runs if r.info.get("engine") != "analytic" and r.has("H")]
    if not engines:
        return None
    checks = {(c["quantity"], c["a"]): c for c in scene.get("checks", []) if c["group"].endswith(".drift")}
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.4), sharex=True)
    reasons = {"H": scene.get("momentum_not_conserved", ""), "E": scene.get("energy_not_conserved", "")}
    for ax, x in zip(axes, ("H", "E")):
        relative = True
        for r in engines:
            if not r.has(x):
                continue
            v = r.col(x)
            x0 = v[0]
            relative = relative and abs(x0) > 0
            d = np.abs(v - x0) / (abs(x0) if abs(x0) > 0 else 1.0)
            ax.semilogy(r.t, np.maximum(d, TINY), label=r.label, **{k: s for k, s in r.style.items() if k != "alpha"})
            c = checks.get((x + ".drift", r.label))
            if c and c["status"] in ("PASS", "FAIL") and c["bound"]:
                ax.axhline(c["bound"] / (abs(x0) if abs(x0) > 0 else 1.0), color=r.style["color"],
                           linestyle="--", linewidth=0.9, alpha=0.7)
        unit = "" if relative else (" (kg m^2/s)" if x == "H" else " (J)")
        ax.set_ylabel(("|%s(t) - %s(0)| / |%s(0)|" % (x, x, x)) if relative else ("|%s(t) - %s(0)|%s" % (x, x, unit)))
        title = "drift of %s from its initial value" % x
        if reasons[x]:
            title += " (not checked: not conserved, %s)" % reasons[x]
        ax.set_title(title, fontsize="medium")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="lower right", fontsize="small")
    axes[-1].set_xlabel("time t (s)")
    fig.suptitle("Conservation: drift of H and E of each engine (log scale)\n"
                 "dashed lines: the drift tolerance atol + rtol |X(0)| of each engine's check")
    fig.tight_layout()
    name = "%s-drift.png" % sid
    save_figure(fig, os.path.join(out_dir, name))
    return name, ("Relative drift |X(t) - X(0)| / |X(0)| of the angular momentum magnitude H and "
                  "the energy E of each engine (absolute drift where X(0) = 0). In a scene without "
                  "external torques H is conserved; without dampers, motors or external torques E "
                  "is too, so the drift measures integration and formulation error.")


CHARTS = [chart_base_w, chart_joints, chart_modal, chart_H_E, chart_differences, chart_drift]


# ----------------------------------------------------------------------------------------------
# Pages


def page(title, body):
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<title>%s</title>\n<style>%s</style>\n</head>\n<body>\n%s\n</body>\n</html>\n"
            % (esc(title), CSS, body))


def table(header, rows, classes=None):
    out = ["<table>", "<tr>" + "".join("<th>%s</th>" % esc(h) for h in header) + "</tr>"]
    for i, row in enumerate(rows):
        cls = (classes[i] if classes else "") or ""
        out.append("<tr%s>" % (' class="%s"' % cls if cls else "") + "".join(
            "<td%s>%s</td>" % (' class="num"' if num else "", cell) for cell, num in row) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def vec(v):
    return "(" + ", ".join(gfmt(x) for x in v) + ")"


PASS_RULE = """<p>How to read the checks. For every pair of runs <i>a</i> and <i>b</i> (<i>b</i> is
the reference: the analytic solution when there is one, else the engine listed first) and every
quantity, the check passes when</p>
<pre>max over the run of |a(t) - b(t)|  &lt;=  atol + rtol * max over the run of |b(t)|</pre>
<p>Attitudes are compared as the rotation angle (rad) between the two attitudes, so q and -q agree;
their scale max|b| is 1. Each engine's drift check passes when
<code>max |X(t) - X(0)| &lt;= atol + rtol * |X(0)|</code> for X = H, E. The <i>normalised error</i>
is the error divided by that bound: 1 or less passes. Tolerances come from the scene's
<code>compare</code> block (a quantity, its vector such as <code>main.w</code>, its group, or the
default).</p>"""


def scene_page(scene, out_dir):
    sid = scene["id"]
    status = "PASS" if scene.get("passed") else "FAIL"
    parts = ['<p><a href="index.html">&larr; all scenes</a></p>',
             '<h1>%s <span class="badge %s">%s</span></h1>' % (esc(scene.get("scene")), status, status),
             '<p class="note">Scene file: <code>%s</code></p>' % esc(scene.get("path"))]
    counts = {}
    for c in scene.get("checks", []):
        counts[c["status"]] = counts.get(c["status"], 0) + 1
    if counts:
        parts.append("<p>%d checks: %d passed, %d failed, %d excluded, %d skipped. %s</p>" % (
            sum(counts.values()), counts.get("PASS", 0), counts.get("FAIL", 0),
            counts.get("EXCLUDED", 0), counts.get("SKIPPED", 0),
            "Failed checks are listed first in the table at the end." if counts.get("FAIL") else ""))
    if scene.get("input_error"):
        parts.append("<h2>Bad input</h2><pre>%s</pre>" % esc(scene["input_error"]))
        return page(scene.get("scene", sid), "\n".join(parts)), []

    system = scene.get("system", {})
    runs = [Run(info, out_dir, i) for i, info in enumerate(scene.get("runs", []))]
    parts.append("<h2>What this scene is</h2>")
    parts.append("<p>%s</p>" % esc(system.get("description", "")))
    parts.append("<p><b>Source and assumptions.</b> %s</p>" % esc(system.get("source", "")))

    # Scene data.
    parts.append("<h2>Scene data (SI units)</h2>")
    rows = []
    for b in system.get("bodies", []):
        inertia = b["inertia_kg_m2"]
        diag = all(abs(inertia[i][j]) == 0 for i in range(3) for j in range(3) if i != j)
        rows.append([(esc(b["name"]), False), (gfmt(b["mass_kg"]), True),
                     (("diag" + vec([inertia[i][i] for i in range(3)])) if diag else
                      esc(json.dumps(inertia)), False),
                     (esc(", ".join(b.get("modes", []))) or "rigid", False),
                     (esc(json.dumps(b["torque_N_m"])) + " (" + b["torque_frame"] + " frame)"
                      if b.get("torque_N_m") else "none", False)])
    parts.append(table(["body", "mass (kg)", "inertia about CM, body axes (kg m^2)",
                        "flexible modes", "external torque (N m), from time t (s)"], rows))
    rows = []
    for j in system.get("joints", []):
        if j["type"] == "free":
            ini = j.get("initial", {})
            geometry = "base body, parent is the inertial frame N"
            initial = "w_NB_B = %s rad/s, q_NB = %s" % (vec(ini.get("w_NB_B_rad_s", [])), vec(ini.get("q_NB", [])))
        else:
            geometry = "parent point %s m, child point %s m" % (vec(j["parent_point_m"]), vec(j["child_point_m"]))
            if "axis" in j:
                geometry += ", axis %s (parent frame)" % vec(j["axis"])
            ini = j.get("initial", {})
            if j["type"] == "revolute":
                initial = "angle %s rad, rate %s rad/s" % (gfmt(ini.get("angle_rad")), gfmt(ini.get("rate_rad_s")))
            elif j["type"] == "spherical":
                initial = "q_J %s, w_PC_C %s rad/s" % (vec(ini.get("q_J", [])), vec(ini.get("w_PC_C_rad_s", [])))
            else:
                initial = "-"
        loads = []
        for key, label in (("stiffness_N_m_rad", "stiffness %s N m/rad"), ("damping_N_m_s_rad", "damping %s N m s/rad"),
                           ("neutral_angle_rad", "neutral angle %s rad")):
            if key in j:
                loads.append(label % gfmt(j[key]))
        if "motor_N_m" in j:
            loads.append("motor " + ", ".join("%s N m from t = %s s" % (esc(json.dumps(m["value"])), gfmt(m["from_t"]))
                                              for m in j["motor_N_m"]))
        rows.append([(esc(j["name"]), False), (esc(j["type"]), False),
                     (esc("%s -> %s" % (j["parent"], j["child"])), False), (esc(geometry), False),
                     (esc(initial), False), (esc("; ".join(loads)) or "none", False)])
    parts.append(table(["joint", "type", "parent -> child", "geometry", "initial state", "loads"], rows))
    run = system.get("run", {})
    settings = scene.get("settings", {})
    parts.append("<p>Run: 0 to %s s, output every %s s, integrator %s (rtol %s, atol %s). Total linear "
                 "momentum %s.%s</p>" % (
                     gfmt(settings.get("duration_s", run.get("duration_s"))),
                     gfmt(settings.get("output_step_s", run.get("output_step_s"))),
                     esc(settings.get("integrator", run.get("integrator"))),
                     gfmt(settings.get("rtol")), gfmt(settings.get("atol")),
                     "zero" if system.get("zero_linear_momentum") else "as given",
                     (" Analytic reference: %s (closed-form solution, run 'analytic')." % esc(system["analytic"]))
                     if system.get("analytic") else ""))
    comp = system.get("compare", {})
    rows = [[("default", False), (sci(comp.get("default", {}).get("atol")), True),
             (sci(comp.get("default", {}).get("rtol")), True), ("", False)]]
    for t in comp.get("tolerances", []):
        rows.append([(esc(t["quantity"]), False), (sci(t["atol"]), True), (sci(t["rtol"]), True), ("", False)])
    for x in comp.get("excluded", []):
        rows.append([(esc(x["quantity"]), False), ("-", True), ("-", True), ("excluded: " + esc(x["reason"]), False)])
    parts.append(table(["tolerance key", "atol", "rtol", "note"], rows))

    # Runs.
    parts.append("<h2>Runs</h2>")
    rows, classes = [], []
    for r in scene.get("runs", []):
        failure = r.get("failure")
        note = r.get("note", "")
        if r["engine"] == "analytic":
            note = "closed-form torque-free solution (Jacobi elliptic functions)"
        rows.append([(esc(r["label"]), False), (esc(r["state"]), False), (str(r["rows"]), True),
                     (str(r["rhs_calls"]) if r["engine"] != "analytic" else "-", True),
                     (str(r["steps"]) if r["engine"] != "analytic" else "-", True),
                     (gfmt(r["wall_seconds"], 3) if r["engine"] != "analytic" else "-", True),
                     (esc(note) + (" (failed at t = %s s)" % gfmt(failure["time"]) if failure else ""), False)])
        classes.append({"ok": "", "failed": "FAIL", "skipped": "SKIPPED"}.get(r["state"], ""))
    parts.append(table(["run", "state", "output rows", "rhs calls", "steps", "wall time (s)", "note"], rows, classes))

    # Charts.
    parts.append("<h2>Charts</h2>")
    images = []
    for chart in CHARTS:
        try:
            made = chart(scene, runs, out_dir, sid)
        except Exception as e:  # a chart that cannot be drawn must not lose the page
            print("make_report.py: %s: %s failed: %s" % (sid, chart.__name__, e), file=sys.stderr)
            plt.close("all")
            made = None
        if made:
            name, caption = made
            images.append(name)
            parts.append('<figure><img src="%s" alt="%s"><figcaption>%s</figcaption></figure>'
                         % (esc(name), esc(caption), esc(caption)))
    if not images:
        parts.append("<p>No run produced data to draw.</p>")

    # Checks.
    parts.append("<h2>Checks</h2>")
    parts.append(PASS_RULE)
    rows, classes = [], []
    order = {"FAIL": 0, "PASS": 1, "EXCLUDED": 2, "SKIPPED": 3}
    for c in sorted(scene.get("checks", []), key=lambda c: order.get(c["status"], 9)):
        numbers = c["status"] in ("PASS", "FAIL") and c["group"] != "run"
        rows.append([(esc(c["quantity"]), False),
                     (esc(c["a"] + (" vs " + c["b"] if c["b"] else "")), False),
                     (sci(c["error"]) if numbers else "-", True),
                     (gfmt(c["time"]) if numbers or (c["group"] == "run" and c["status"] == "FAIL") else "-", True),
                     (gfmt(c["first_exceeded"]) if c.get("first_exceeded") is not None else "-", True),
                     (sci(c["atol"], 2) if numbers else "-", True),
                     (sci(c["rtol"], 2) if numbers else "-", True),
                     (sci(c["scale"]) if numbers else "-", True),
                     (sci(c["bound"]) if numbers else "-", True),
                     (sci(c["normalised"]) if numbers else "-", True),
                     (c["status"], False),
                     (esc(c["note"] or ("tolerance '%s'" % c["tolerance_key"]
                                        if c["tolerance_key"] not in ("default", "-") else "")), False)])
        classes.append(c["status"])
    parts.append(table(["quantity", "a vs b (reference)", "max error", "at t (s)", "first over (s)",
                        "atol", "rtol", "scale max|b|", "bound", "normalised", "result", "note"],
                       rows, classes))
    if scene.get("notes"):
        parts.append("<h2>Notes</h2><ul>%s</ul>" % "".join("<li>%s</li>" % esc(n) for n in scene["notes"]))
    return page("crossdyn: " + scene.get("scene", sid), "\n".join(parts)), images


def index_page(summary):
    groups = summary.get("group_order", [])
    present = [g for g in groups if any(x["group"] == g for s in summary["scenes"] for x in s.get("groups", []))]
    rows, classes = [], []
    for s in summary["scenes"]:
        cells = [('<a href="%s">%s</a>' % (esc(s["page"]), esc(s.get("scene"))), False)]
        by = {x["group"]: x for x in s.get("groups", [])}
        for g in present:
            x = by.get(g)
            if not x:
                cells.append(("-", False))
            elif g == "run":
                ok = x["checks"] - x["failed"] - x["skipped"]
                text = ("FAIL: %d failed" % x["failed"]) if x["failed"] else "%d ran" % ok
                if x["skipped"]:
                    text += ", %d skipped" % x["skipped"]
                cells.append(('<span class="badge %s">%s</span>' % (x["status"], esc(text)), False))
            elif x["status"] in ("PASS", "FAIL"):
                cells.append(('<span class="badge %s" title="%s">%s %s</span>'
                              % (x["status"], esc(x["worst_check"]), x["status"], sci(x["worst"], 2)), False))
            else:
                cells.append(('<span class="badge %s">%s</span>' % (x["status"], x["status"].lower()), False))
        result = "BAD INPUT" if s.get("input_error") else ("PASS" if s["passed"] else "FAIL")
        cells.append(('<span class="badge %s">%s</span>' % ("FAIL" if result != "PASS" else "PASS", result), False))
        rows.append(cells)
        classes.append("")
    counts = summary.get("counts", {})
    body = ["<h1>crossdyn verification report</h1>",
            "<p>Each scene was run through independently written dynamics engines (Kane, Lagrange "
            "with quasi-coordinates, Newton-Euler) and, where the scene has one, a closed-form "
            "analytic solution; every pair of runs was compared quantity by quantity, and each "
            "engine's angular momentum H and energy E were checked for drift.</p>",
            "<p><b>%s</b>: %d scenes (%d failed, %d unreadable), %d checks, %d failed.</p>" % (
                "ALL PASS" if summary.get("passed") else "FAILURES",
                counts.get("scenes", 0), counts.get("scenes_failed", 0), counts.get("scenes_unreadable", 0),
                counts.get("checks", 0), counts.get("checks_failed", 0)),
            "<p>Each cell gives the worst <i>normalised error</i> of that kind of check in the scene "
            "(error divided by its tolerance; 1 or less passes). Hover a cell for the check "
            "behind it; the scene's page has every number and the charts.</p>",
            table(["scene"] + [GROUP_TITLES.get(g, g) for g in present] + ["result"], rows, classes),
            PASS_RULE]
    return page("crossdyn verification report", "\n".join(body))


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    summary_path, out_dir = argv[1], argv[2]
    try:
        with open(summary_path, encoding="utf-8") as f:
            summary = json.load(f)
    except (OSError, ValueError) as e:
        print("make_report.py: cannot read %s: %s" % (summary_path, e), file=sys.stderr)
        return 2
    os.makedirs(out_dir, exist_ok=True)
    for scene in summary.get("scenes", []):
        scene.setdefault("group_order", summary.get("group_order", []))
        html_text, _ = scene_page(scene, out_dir)
        write_atomic(os.path.join(out_dir, scene["page"]), html_text)
    write_atomic(os.path.join(out_dir, "index.html"), index_page(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
