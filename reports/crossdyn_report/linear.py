"""`crossdyn linearize --report DIR` (linearize.json, "kind": "linearize"): every engine's
eigenvalues overlaid on the complex plane, their differences between engines on a log scale, each
mode drawn on the scene; with --vary, the root locus against the swept parameter."""

import os

import numpy as np

from . import scene_view
from .common import gfmt, plt, save_figure, write_atomic

# One look per engine, the same on every chart (the first engine is the reference of the checks).
MARKERS = ["o", "x", "+", "s", "d", "^"]
COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2"]


def _engines(lin):
    return [e for e in lin["engines"] if "failure" not in e]


def _eigs(e):
    return np.array([complex(v["re"], v["im"]) for v in e["eigenvalues"]])


def chart_plane(lin, out_dir, name):
    """The eigenvalues of every engine on the complex plane, zeros included."""
    engines = _engines(lin)
    if not engines:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    for k, e in enumerate(engines):
        ev = _eigs(e)
        if k == 0:  # hollow circles under the others' crosses
            ax.scatter(ev.real, ev.imag, marker="o", s=70, facecolors="none", edgecolors=COLOURS[0],
                       label=e["label"], linewidths=1.3)
        else:
            ax.scatter(ev.real, ev.imag, marker=MARKERS[k % len(MARKERS)], s=45, color=COLOURS[k % len(COLOURS)],
                       label=e["label"], linewidths=1.3)
    ax.axvline(0, color="0.6", lw=0.8)
    ax.axhline(0, color="0.85", lw=0.8)
    ax.set_xlabel("Re lambda (1/s): right of the line grows")
    ax.set_ylabel("Im lambda (rad/s)")
    ax.set_title("Eigenvalues of each engine's linear model (%s)" % lin["scene"], fontsize=10.5)
    ax.legend(fontsize=8.5)
    ax.grid(alpha=0.3)
    save_figure(fig, os.path.join(out_dir, name))
    return name


def chart_differences(lin, out_dir, name):
    """Per mode, |lambda_a - lambda_b| / |lambda_a| of every engine pair, log scale, with the bound."""
    checks = [c for c in lin["checks"] if c["kind"] == "eigenvalue"]
    if not checks:
        return None
    modes = []
    for c in checks:
        key = (c["a"]["re"], c["a"]["im"])
        if key not in modes:
            modes.append(key)
    pairs = []
    for c in checks:
        if c["engine_b"] not in pairs:
            pairs.append(c["engine_b"])
    fig, ax = plt.subplots(figsize=(max(6.5, 0.55 * len(modes) + 3), 4.2))
    floor = 1e-17
    for k, p in enumerate(pairs):
        xs, ys, bs = [], [], []
        for c in checks:
            if c["engine_b"] != p:
                continue
            a = abs(complex(c["a"]["re"], c["a"]["im"]))
            i = modes.index((c["a"]["re"], c["a"]["im"]))
            err = c["error"] if c["error"] is not None else np.inf
            xs.append(i + 1 + 0.12 * (k - (len(pairs) - 1) / 2))
            ys.append(max(err / a, floor))
            bs.append(c["bound"] / a)
        ax.scatter(xs, ys, marker=MARKERS[(k + 1) % len(MARKERS)], color=COLOURS[(k + 1) % len(COLOURS)], s=45,
                   label="%s vs %s" % (checks[0]["engine_a"], p), zorder=3)
        ax.scatter(xs, bs, marker="_", color=COLOURS[(k + 1) % len(COLOURS)], s=180, zorder=2)
    ax.set_yscale("log")
    ax.set_xticks(range(1, len(modes) + 1))
    ax.set_xlabel("mode (as in the table)")
    ax.set_ylabel("|lambda_a - lambda_b| / |lambda_a|")
    ax.set_title("Differences between engines per mode (dash: the bound; at %g: zero)" % floor, fontsize=10.5)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8.5)
    save_figure(fig, os.path.join(out_dir, name))
    return name


def chart_locus(locus, out_dir, name):
    """The root locus: each engine's eigenvalues on the complex plane coloured by the parameter,
    and the modes' natural frequency and real part against it."""
    pts = [p for p in locus["points"] if "linearization" in p]
    if not pts:
        return None
    values = np.array([p["value"] for p in pts])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    cmap = plt.get_cmap("viridis")
    norm = plt.Normalize(values.min(), values.max() if values.max() > values.min() else values.min() + 1)
    labels = [e["label"] for e in _engines(pts[0]["linearization"])]
    for k, label in enumerate(labels):
        for p in pts:
            es = [e for e in _engines(p["linearization"]) if e["label"] == label]
            if not es:
                continue
            ev = _eigs(es[0])
            col = cmap(norm(p["value"]))
            if k == 0:
                axes[0].scatter(ev.real, ev.imag, marker="o", s=40, facecolors="none", edgecolors=[col], linewidths=1.1)
            else:
                axes[0].scatter(ev.real, ev.imag, marker=MARKERS[k % len(MARKERS)], s=25, color=[col], linewidths=1.1)
            nz = ev[np.abs(ev) > 0]
            axes[1].scatter([p["value"]] * len(nz), np.abs(nz), marker=MARKERS[k % len(MARKERS)],
                            color=COLOURS[k % len(COLOURS)], s=25, label=label if p is pts[0] else None)
            axes[2].scatter([p["value"]] * len(ev), ev.real, marker=MARKERS[k % len(MARKERS)],
                            color=COLOURS[k % len(COLOURS)], s=25, label=label if p is pts[0] else None)
    axes[0].axvline(0, color="0.6", lw=0.8)
    axes[0].set_xlabel("Re lambda (1/s)")
    axes[0].set_ylabel("Im lambda (rad/s)")
    axes[0].set_title("eigenvalues, coloured by %s" % locus["vary"], fontsize=10)
    fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes[0], label="%s %s" % (locus["vary"], locus["unit"]))
    unit = " (%s)" % locus["unit"] if locus["unit"] else ""
    axes[1].set_xlabel(locus["vary"] + unit)
    axes[1].set_ylabel("|lambda| (rad/s)")
    axes[1].set_title("natural frequencies", fontsize=10)
    axes[2].axhline(0, color="0.6", lw=0.8)
    axes[2].set_xlabel(locus["vary"] + unit)
    axes[2].set_ylabel("Re lambda (1/s): above 0 grows")
    axes[2].set_title("real parts", fontsize=10)
    if values.min() > 0 and values.max() / values.min() > 50:
        for ax in axes[1:]:
            ax.set_xscale("log")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8)
    fig.subplots_adjust(wspace=0.42, left=0.05, right=0.98)
    save_figure(fig, os.path.join(out_dir, name))
    return name


def mode_pictures(summary, out_dir):
    """Each drawn mode: [(file, caption)]."""
    lin = summary["linearization"]
    out = []
    for pic in summary.get("mode_pictures", []):
        k = pic["mode"]
        if not pic.get("geometry"):
            out.append(dict(name=None, mode=k, caption="Mode %d (%s) moves no joint or modal coordinate: a mode of the "
                            "base's angular velocity (its attitude is not among the reduced coordinates)." % (k, pic["coordinate"])))
            continue
        geom = scene_view.load(os.path.join(out_dir, pic["geometry"]))
        engine = [e for e in lin["engines"] if e["label"] == pic["engine"]][0]
        md = engine["modes"][k - 1]
        lam = complex(md["lambda"]["re"], md["lambda"]["im"])
        fig = plt.figure(figsize=(12, 3.5))
        scene_view.draw_motion(fig, geom, 4)
        fig.suptitle("mode %d: %s, lambda = %s%+.6gi (w_n %s rad/s, zeta %s), exaggerated; %s's output rows"
                     % (k, pic["coordinate"], gfmt(lam.real, 6), lam.imag, gfmt(md["frequency"], 6),
                        gfmt(md["damping_ratio"], 3), pic["engine"]), fontsize=10, y=0.985)
        name = "mode-%d.png" % k
        save_figure(fig, os.path.join(out_dir, name))
        period = ("a quarter period apart" if lam.imag != 0 else "1/(2 |lambda|) apart")
        out.append(dict(name=name, mode=k, caption=(
            "Mode %d (%s): the scene at the operating point displaced along the mode, at four times %s "
            "(z0 + a Re(v e^(lambda t)), the largest joint or modal coordinate moved by 0.35 rad or m: "
            "exaggerated)." % (k, pic["coordinate"], period))))
    return out


def _mode_rows(lin):
    engines = _engines(lin)
    if not engines:
        return [], []
    ref = engines[0]
    rows = []
    for i, md in enumerate(ref["modes"]):
        lam = complex(md["lambda"]["re"], md["lambda"]["im"])
        cells = []
        for e in engines:
            best = min(e["modes"], key=lambda m: abs(complex(m["lambda"]["re"], m["lambda"]["im"]) - lam), default=None)
            cells.append("n/a" if best is None else "%s / %s" % (gfmt(best["frequency"], 10), gfmt(best["damping_ratio"], 3)))
        worst = [c for c in lin["checks"] if c["kind"] == "eigenvalue" and (c["a"]["re"], c["a"]["im"]) == (lam.real, lam.imag)]
        agree = max((c["error"] / abs(lam) if c["error"] is not None else float("inf")) for c in worst) if worst else None
        ok = all(c["passed"] for c in worst)
        rows.append(dict(index=i + 1, coordinate=md["coordinate"], lam="%s %+.8gi" % (gfmt(lam.real, 8), lam.imag),
                         cells=cells, agree="n/a" if agree is None else "%.1e" % agree, ok=ok,
                         grows=lam.real > 0 and lam.real > 1e-8 * abs(lam)))
    return [e["label"] for e in engines], rows


def report(summary, out_dir, env, render, warn):
    charts = []
    ctx = dict(title="crossdyn linearize: %s" % summary.get("scene", ""), scene=summary.get("scene", ""),
               locus=None, points=[], lin=None, labels=[], rows=[], failed=[], pictures=[])
    if "locus" in summary:
        locus = summary["locus"]
        name = chart_locus(locus, out_dir, "root-locus.png")
        if name:
            charts.append(dict(name=name, caption=(
                "Root locus against %s: every engine's eigenvalues (first engine hollow circles, the "
                "others filled), coloured by the parameter's value; then each non-zero eigenvalue's "
                "|lambda| and real part against it. A real part above 0 is a mode that grows." % locus["description"])))
        points = []
        for p in locus["points"]:
            if "linearization" not in p:
                points.append(dict(value=gfmt(p["value"]), verdict="refused", detail=p.get("refused", ""), modes=""))
                continue
            lin = p["linearization"]
            labels, rows = _mode_rows(lin)
            points.append(dict(value=gfmt(p["value"]), verdict="PASS" if lin["passed"] else "FAIL",
                               detail="; ".join(lin["findings"]),
                               modes=", ".join("%s%s" % (r["cells"][0], " (grows)" if r["grows"] else "") for r in rows)))
        ctx.update(locus=locus, points=points)
    else:
        lin = summary["linearization"]
        for name, fn, cap in (("eigenvalues.png", chart_plane, (
                "Every engine's eigenvalues on the complex plane (zeros included): where the engines "
                "agree the markers coincide.")),
                              ("differences.png", chart_differences, (
                "For each mode of the table, each engine's eigenvalue against the first engine's, "
                "relative, log scale; the dash is the check's bound (its rtol plus the finite "
                "differences' allowance)."))):
            made = fn(lin, out_dir, name)
            if made:
                charts.append(dict(name=made, caption=cap))
        labels, rows = _mode_rows(lin)
        failed = [c for c in lin["checks"] if not c["passed"]]
        ctx.update(lin=lin, labels=labels, rows=rows, failed=failed, pictures=mode_pictures(summary, out_dir))
    ctx["charts"] = charts
    write_atomic(os.path.join(out_dir, "index.html"), render(env, "linearize.html", ctx))
    return 0
