"""`crossdyn stability --report DIR` (stability.json, "kind": "stability"): one map per engine,
parameter values across, integrator x step (or tolerance) down, cells coloured by class."""

import os

import numpy as np
from matplotlib.colors import to_rgb
from matplotlib.patches import Patch

from .common import gfmt, plt, save_figure, write_atomic

# One colour per class, in stability.json's "classes" order (harness/stability.hpp):
# accurate, inaccurate, drift, diverged, singular, too costly, no reference.
CLASS_COLOURS = {
    "accurate": "#4daf4a",
    "inaccurate": "#ffd92f",
    "drift": "#fdae61",
    "diverged": "#d7191c",
    "singular": "#7b3294",
    "too costly": "#2b83ba",
    "no reference": "#bdbdbd",
}


def _rows(m, engine):
    """(integrator, setting, setting_text) in map order, for one engine."""
    out = []
    for integ in m["integrators"]:
        seen = []
        for c in m["cells"]:
            if c["engine"] == engine and c["integrator"] == integ and c["setting"] not in [s for s, _ in seen]:
                seen.append((c["setting"], c["setting_text"]))
        out += [(integ, s, t) for s, t in seen]
    return out


def chart_map(m, out_dir):
    """One panel per engine. Returns (file name, caption) or None."""
    engines = [e for e in m["engines"] if any(c["engine"] == e for c in m["cells"])]
    if not engines or not m["columns"]:
        return None
    classes = list(CLASS_COLOURS)
    nrows = max(len(_rows(m, e)) for e in engines)
    ncols = len(m["columns"])
    fig, axes = plt.subplots(len(engines), 1, figsize=(max(7.0, 0.95 * ncols + 3.4), (0.3 * nrows + 1.6) * len(engines) + 0.8),
                             squeeze=False)
    # Within its class a cell is shaded by the size of its error (issue 24): log10 of the history
    # error, from the class's smallest error on this map (full colour) to its largest (mixed half
    # with white); the exponent is printed in cells without another number.
    logs = {}
    for c in m["cells"]:
        e = c.get("history_error")
        if e is not None and np.isfinite(e) and e > 0:
            logs.setdefault(c["class"], []).append(np.log10(e))
    span = {k: (min(v), max(v)) for k, v in logs.items()}

    def shade(c):
        rgb = np.array(to_rgb(CLASS_COLOURS[c["class"]]))
        e = c.get("history_error")
        if c["class"] not in span or e is None or not np.isfinite(e) or e <= 0:
            return rgb
        lo, hi = span[c["class"]]
        t = 0.0 if hi <= lo else (np.log10(e) - lo) / (hi - lo)
        return rgb + (1.0 - rgb) * 0.5 * t

    for ax, engine in zip(axes[:, 0], engines):
        rows = _rows(m, engine)
        grid = np.full((len(rows), ncols), np.nan)
        image = np.ones((len(rows), ncols, 4))
        image[:, :, 3] = 0.0  # no cell: transparent
        text = [["" for _ in range(ncols)] for _ in rows]
        for c in m["cells"]:
            if c["engine"] != engine:
                continue
            i = rows.index((c["integrator"], c["setting"], c["setting_text"]))
            grid[i, c["column"]] = classes.index(c["class"])
            image[i, c["column"], :3] = shade(c)
            image[i, c["column"], 3] = 1.0
            if c.get("h_lambda") is not None and c["class"] != "no reference":
                text[i][c["column"]] = "%.2g" % c["h_lambda"]
            elif c.get("history_error") is not None and np.isfinite(c["history_error"]) and c["history_error"] > 0:
                text[i][c["column"]] = "%d" % int(np.floor(np.log10(c["history_error"])))
        ax.imshow(image, aspect="auto", interpolation="nearest")
        for i in range(len(rows)):
            for j in range(ncols):
                if text[i][j]:
                    ax.text(j, i, text[i][j], ha="center", va="center", fontsize=7, color="black")
        # Lines between integrators.
        for i in range(1, len(rows)):
            if rows[i][0] != rows[i - 1][0]:
                ax.axhline(i - 0.5, color="white", linewidth=3)
        ax.set_yticks(range(len(rows)))
        ax.set_yticklabels(["%s %s" % (r[0], r[2]) for r in rows], fontsize=8)
        ax.set_xticks(range(ncols))
        ax.set_xticklabels([gfmt(c["value"]) for c in m["columns"]], fontsize=8, rotation=30)
        p = m["parameter"]
        ax.set_xlabel("%s%s" % (p["spec"], (" (%s)" % p["unit"]) if p["unit"] else ""))
        ax.set_title(engine, fontsize="medium")
        e_index = m["engines"].index(engine)
        lam = [(c.get("lambda_max") or [None] * len(m["engines"]))[e_index] for c in m["columns"]]
        if any(x is not None for x in lam):
            top = ax.secondary_xaxis("top")
            top.set_xticks(range(ncols))
            top.set_xticklabels(["%.3g" % x if x is not None else "-" for x in lam], fontsize=7)
            top.set_xlabel("|lambda|max, 1/s", fontsize=8)
    present = sorted({c["class"] for c in m["cells"]}, key=classes.index)
    fig.legend(handles=[Patch(facecolor=CLASS_COLOURS[k], label=k) for k in present], loc="lower center",
               ncol=len(present), frameon=False, bbox_to_anchor=(0.5, 0.0))
    fig.tight_layout(rect=(0, 0.8 / fig.get_size_inches()[1], 1, 1))
    name = "%s.png" % m["id"]
    save_figure(fig, os.path.join(out_dir, name))
    return name, ("Each cell is one run of %s: the engine (panel) with the integrator and step or "
                  "tolerance (row) at one value of %s (column), coloured by its class, and shaded "
                  "within its class by the size of its history error (full colour: the class's "
                  "smallest error on this map; paler: larger). Numbers in rk4 cells are h |lambda|max: "
                  "rk4 is stable only below about 2.8; in the other cells, the exponent of the history "
                  "error (-7: 1e-7 to 1e-6). |lambda|max (top axis) is "
                  "the largest |eigenvalue| of that engine's right-hand-side Jacobian at t = 0."
                  % (m["scene"], m["parameter"]["description"]))


def chart_cost(m, out_dir):
    """Right-hand sides of the cheapest accurate run of each engine x integrator against the
    parameter: what it costs to be accurate. Returns (file name, caption) or None."""
    engines = [e for e in m["engines"] if any(c["engine"] == e for c in m["cells"])]
    values = [c["value"] for c in m["columns"]]
    fig, ax = plt.subplots(figsize=(9.5, 5.0))
    colours = ["#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d", "#666666"]
    markers = ["o", "s", "^", "D", "v", "P", "X", "*"]
    dashes = ["-", "--", ":", "-."]
    drawn = 0
    for ei, engine in enumerate(engines):
        for ii, integ in enumerate(m["integrators"]):
            xs, ys = [], []
            for col, v in enumerate(values):
                ok = [c["rhs_calls"] for c in m["cells"] if c["engine"] == engine and c["integrator"] == integ
                      and c["column"] == col and c["class"] == "accurate" and c["rhs_calls"] > 0]
                if ok:
                    xs.append(v)
                    ys.append(min(ok))
            if xs:
                ax.plot(xs, ys, color=colours[ii % len(colours)], marker=markers[ei % len(markers)],
                        linestyle=dashes[ei % len(dashes)], label="%s + %s" % (engine, integ))
                drawn += 1
    if not drawn:
        plt.close(fig)
        return None
    if all(v > 0 for v in values):
        ax.set_xscale("log")
    ax.set_yscale("log")
    p = m["parameter"]
    ax.set_xlabel("%s%s" % (p["spec"], (" (%s)" % p["unit"]) if p["unit"] else ""))
    ax.set_ylabel("right-hand sides of the cheapest accurate run")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize="x-small", loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    name = "%s-cost.png" % m["id"]
    save_figure(fig, os.path.join(out_dir, name))
    return name, ("What it costs to be accurate on %s: for each engine (marker and dash) and integrator "
                  "(colour), the right-hand-side calls of its cheapest accurate run at each value of %s; "
                  "a line stops where no setting tried is accurate. Where a fixed step diverges, an "
                  "adaptive method pays in steps instead, and an implicit one in fewer, costlier steps."
                  % (m["scene"], p["spec"]))


def map_context(summary, m, chart, cost=None):
    cells = []
    for c in m["cells"]:
        col = m["columns"][c["column"]]
        cells.append(dict(engine=c["engine"], integrator=c["integrator"], setting=c["setting_text"],
                          value=gfmt(col["value"]), cls=c["class"], why=c["why"],
                          cpu="" if c.get("cpu") is None else "%.3g" % (1e3 * c["cpu"]),
                          rhs=c["rhs_calls"], h_lambda="" if c.get("h_lambda") is None else "%.3g" % c["h_lambda"]))
    p = m["parameter"]
    return dict(title="crossdyn stability: %s against %s" % (m["scene"], p["spec"]), scene=m["scene"],
                file=m.get("file", ""), parameter=p, limits=m["limits"], chart=chart, cost=cost, csv=m["csv"],
                findings=m.get("findings", []), notes=m.get("notes", []), cells=cells,
                engines=m["engines"],
                columns=[dict(value=gfmt(c["value"]),
                              lam=["-" if x is None else "%.3g" % x for x in (c.get("lambda_max") or [])],
                              reference=c.get("reference_note", "")) for c in m["columns"]],
                colours=CLASS_COLOURS)


def index_context(summary):
    maps = [dict(page=m["page"], scene=m["scene"], spec=m["parameter"]["spec"],
                 description=m["parameter"]["description"], findings=m.get("findings", [])[:3])
            for m in summary.get("maps", [])]
    return dict(title="crossdyn: where each method fails", maps=maps)


def report(summary, out_dir, env, render, warn):
    for m in summary.get("maps", []):
        try:
            made = chart_map(m, out_dir)
        except Exception as e:  # a chart that cannot be drawn must not lose the page
            warn("%s: the stability map failed: %r" % (m.get("scene"), e))
            plt.close("all")
            made = None
        chart = dict(name=made[0], caption=made[1]) if made else None
        try:
            made = chart_cost(m, out_dir)
        except Exception as e:
            warn("%s: the cost chart failed: %r" % (m.get("scene"), e))
            plt.close("all")
            made = None
        cost = dict(name=made[0], caption=made[1]) if made else None
        write_atomic(os.path.join(out_dir, m["page"]),
                     render(env, "stability.html", map_context(summary, m, chart, cost)))
    write_atomic(os.path.join(out_dir, "index.html"), render(env, "stability_index.html", index_context(summary)))
    return 0
