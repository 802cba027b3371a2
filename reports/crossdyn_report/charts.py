"""The time-history charts of a scene page. Each chart function returns (file name, caption) or None
when the scene has nothing to show (no joints, no flexible bodies, no data).

Legends sit outside the axes (to the right), so they never hide data. In the joints chart colour
tells the joints apart and the line style the engines."""

import os

import numpy as np

from .common import DASHES, STYLES, gfmt, plt, save_figure
from .kinematics import attitude, attitude_angle, joint_rotation_vectors, rotation_vector

TINY = 1e-17  # floor for log-scale plots of differences that are exactly zero
LEGEND_RIGHT = 0.80  # charts keep the right 20 % of the figure for their legends

GROUP_TITLES = {
    "run": "engine runs",
    "t": "output times",
    "w": "angular velocities",
    "attitude": "attitudes",
    "rate": "joint rates",
    "angle": "joint angles",
    "position": "positions",
    "torque": "drive torques",
    "modal": "modal coordinates",
    "load": "joint loads",
    "H": "angular momentum H (and M)",
    "E": "energy E (and P)",
    "H.drift": "drift of H",
    "E.drift": "drift of E",
    "H.balance": "balance of H",
    "E.balance": "balance of E",
    "J.drift": "drift of the Jacobi integral J",
    "extra": "extra columns",
}
JOINT_COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
                 "tab:pink", "tab:olive", "tab:cyan", "0.3"]
COMPONENT_COLOURS = ("#d62728", "#2ca02c", "#1f4fd6")


def rad_axis(ax, unit):
    """A secondary axis in degrees for an axis in rad or rad/s."""
    ax.secondary_yaxis("right", functions=(np.degrees, np.radians)).set_ylabel(
        unit.replace("rad", "deg"), fontsize="small")


def outside_legend(fig, ax=None, handles=None, labels=None, title=None, sections=None):
    """A legend to the right of the axes, in the figure's reserved margin. `sections`: a list of
    (title, handles, labels) drawn one under the other in one legend."""
    from matplotlib.lines import Line2D
    if sections is None:
        if handles is None:
            handles, labels = ax.get_legend_handles_labels()
        sections = [(title, handles, labels)]
    all_h, all_l = [], []
    for k, (head, hs, ls) in enumerate(sections):
        if not hs:
            continue
        if head:
            if all_h:
                all_h.append(Line2D([], [], color="none"))
                all_l.append("")
            all_h.append(Line2D([], [], color="none"))
            all_l.append(head)
        all_h += list(hs)
        all_l += list(ls)
    if not all_h:
        return None
    leg = fig.legend(all_h, all_l, loc="upper left", bbox_to_anchor=(LEGEND_RIGHT + 0.005, 0.93),
                     fontsize="small", frameon=False, handlelength=2.6)
    heads = {head for head, _, _ in sections if head}
    for text in leg.get_texts():
        if text.get_text() in heads:
            text.set_weight("bold")
    return leg


def finish(fig, name, out_dir):
    fig.tight_layout(rect=(0, 0, LEGEND_RIGHT, 1))
    save_figure(fig, os.path.join(out_dir, name))
    return name


def plot_lines(ax, runs, column):
    drawn = False
    for r in runs:
        if r.has(column):
            ax.plot(r.t, r.col(column), label=r.label, **r.style)
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


def flexible_paper_figures(scene):
    """The paper's figure numbers for Example 2 (pointing_flex): attitudes about y, modal
    coordinates."""
    return ("11", "12") if scene.get("scene", "").startswith("pointing_flex") else None


def chart_base_w(scene, runs, out_dir, sid):
    system = scene.get("system", {})
    base = system.get("joints", [{}])[0].get("child") if system.get("joints") else None
    if not base or not any(r.has(base + ".wx") for r in runs):
        return None
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
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
    outside_legend(fig, axes[0], title="run")
    axes[-1].set_xlabel("time t (s)")
    figs = paper_figures(scene)
    fig.suptitle("Angular velocity of the base body '%s' in N, components in its own body axes%s"
                 % (base, "\n(%s.wx is the spin rate of the paper's Fig. %s)" % (base, figs[0]) if figs else ""))
    name = finish(fig, "%s-base-w.png" % sid, out_dir)
    return name, ("Inertial angular velocity of the base body %s, resolved in its body frame "
                  "(rad/s; degrees per second on the right axis), every run overlaid. Curves that "
                  "agree lie on top of each other; the dashes let each stay visible." % base)


def _joint_lines(ax, runs, joints, values_of, colours):
    """One line per joint and run: colour = joint, line style = run."""
    for ji, j in enumerate(joints):
        for r in runs:
            v = values_of(r, j)
            if v is not None:
                ax.plot(r.t, v, color=colours[ji % len(colours)], linestyle=r.dash,
                        linewidth=2.4 if r.label == "analytic" else 1.7, alpha=0.9)


def chart_joints(scene, runs, out_dir, sid):
    system = scene.get("system", {})
    joints = [j for j in system.get("joints", [])
              if j["type"] in ("revolute", "spherical", "prismatic", "universal")]
    if not joints:
        return None
    revolute = [j for j in joints if j["type"] == "revolute"]
    spherical = [j for j in joints if j["type"] == "spherical"]
    prismatic = [j for j in joints if j["type"] == "prismatic"]
    universal = [j for j in joints if j["type"] == "universal"]
    # Spherical joints' rotation from the two bodies' attitudes (kinematics.joint_rotation_vectors).
    phis = {}
    for r in runs:
        for j in spherical:
            phi = joint_rotation_vectors(r, system, j)
            if phi is not None:
                phis[(r.label, j["name"])] = phi
    # Rotors (a revolute joint turning more than a full turn in some run, e.g. a reaction wheel at
    # hundreds of rad) get their own panels: on one axis with them a 0.2 rad hinge is a flat line.
    def turned(j):
        spans = [np.nanmax(np.abs(r.col(j["name"] + ".angle"))) for r in runs
                 if r.has(j["name"] + ".angle") and len(r.t)]
        return max(spans) if spans else 0.0
    rotors = [j for j in revolute if turned(j) > 2 * np.pi]
    hinges = [j for j in revolute if j not in rotors]
    panels = []
    if hinges:
        panels += [("rev-angle", hinges), ("rev-rate", hinges)]
    if rotors:
        panels += [("rev-angle", rotors), ("rev-rate", rotors)]
    if prismatic:
        panels += [("pri-position", prismatic), ("pri-rate", prismatic)]
    if universal:
        panels += [("uni-angle", universal), ("uni-rate", universal)]
    if spherical:
        panels += [("sph-angle", None), ("sph-rate", None)] + [("sph-phi", j) for j in spherical]
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 2.5 * len(panels) + 1.0), sharex=True,
                             squeeze=False)
    axes = axes[:, 0]
    colour_of = {j["name"]: JOINT_COLOURS[i % len(JOINT_COLOURS)] for i, j in enumerate(joints)}
    sph_colours = [colour_of[j["name"]] for j in spherical]
    for ax, (kind, joint) in zip(axes, panels):
        if kind in ("rev-angle", "rev-rate"):
            group = joint  # the hinges or the rotors
            what = "rotor" if group and group[0] in rotors else "revolute"
            if kind == "rev-angle":
                _joint_lines(ax, runs, group, lambda r, j: r.col(j["name"] + ".angle")
                             if r.has(j["name"] + ".angle") else None, [colour_of[j["name"]] for j in group])
                ax.set_ylabel("%s angle (rad)" % what)
                rad_axis(ax, "rad")
            else:
                _joint_lines(ax, runs, group, lambda r, j: r.col(j["name"] + ".rate")
                             if r.has(j["name"] + ".rate") else None, [colour_of[j["name"]] for j in group])
                ax.set_ylabel("%s rate (rad/s)" % what)
                rad_axis(ax, "rad/s")
        elif kind in ("pri-position", "pri-rate"):
            col = ".position" if kind == "pri-position" else ".rate"
            _joint_lines(ax, runs, joint, lambda r, j, col=col: r.col(j["name"] + col)
                         if r.has(j["name"] + col) else None, [colour_of[j["name"]] for j in joint])
            ax.set_ylabel("prismatic %s" % ("position (m)" if kind == "pri-position" else "rate (m/s)"))
        elif kind in ("uni-angle", "uni-rate"):
            # Axis 1 solid, axis 2 thin, in the joint's colour (the run's dash kept).
            stem = ".angle" if kind == "uni-angle" else ".rate"
            for ji, j in enumerate(joint):
                for k, width in ((1, 2.0), (2, 1.0)):
                    for r in runs:
                        if r.has(j["name"] + stem + str(k)):
                            ax.plot(r.t, r.col(j["name"] + stem + str(k)), color=colour_of[j["name"]],
                                    linestyle=r.dash, linewidth=width, alpha=0.9)
            ax.set_ylabel("universal %s\n(axis 1 thick, 2 thin)" % ("angles (rad)" if kind == "uni-angle" else "rates (rad/s)"))
            rad_axis(ax, "rad" if kind == "uni-angle" else "rad/s")
        elif kind == "sph-angle":
            _joint_lines(ax, runs, spherical, lambda r, j: np.linalg.norm(phis[(r.label, j["name"])], axis=1)
                         if (r.label, j["name"]) in phis else None, sph_colours)
            ax.set_ylabel("spherical: rotation\nangle |phi| of q_J (rad)")
            rad_axis(ax, "rad")
        elif kind == "sph-rate":
            def rate(r, j):
                cols = [j["name"] + c for c in (".wx", ".wy", ".wz")]
                return np.sqrt(sum(r.col(c) ** 2 for c in cols)) if all(r.has(c) for c in cols) else None
            _joint_lines(ax, runs, spherical, rate, sph_colours)
            ax.set_ylabel("spherical: |w_PC|\n(rad/s)")
            rad_axis(ax, "rad/s")
        else:  # rotation-vector components of one spherical joint
            for k in range(3):
                for r in runs:
                    phi = phis.get((r.label, joint["name"]))
                    if phi is not None:
                        ax.plot(r.t, phi[:, k], color=COMPONENT_COLOURS[k], linestyle=r.dash, linewidth=1.6)
            ax.set_ylabel("%s: phi_x, phi_y,\nphi_z of q_J (rad)" % joint["name"])
            rad_axis(ax, "rad")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time t (s)")
    # Outside the axes: joints by colour, runs by line style (and components by colour).
    from matplotlib.lines import Line2D
    sections = [("joint (colour)", [Line2D([], [], color=colour_of[j["name"]], lw=2.2) for j in joints],
                 [j["name"] for j in joints]),
                ("run (line style)", [Line2D([], [], color="0.2", linestyle=r.dash, lw=1.7) for r in runs],
                 [r.label for r in runs])]
    if spherical:
        sections.append(("phi component", [Line2D([], [], color=c, lw=2.2) for c in COMPONENT_COLOURS],
                         ["phi_x", "phi_y", "phi_z"]))
    outside_legend(fig, sections=sections)
    figs = paper_figures(scene)
    fig.suptitle("Joint motion: each child body relative to its parent%s"
                 % ("\n(hinge1.rate and hinge2.rate are the deployment rates of the paper's Fig. %s)" % figs[1]
                    if figs and revolute else ""))
    name = finish(fig, "%s-joints.png" % sid, out_dir)
    caption = ""
    if revolute:
        caption += ("Revolute joints: angle (rad) and rate (rad/s) of each child about its hinge axis, "
                    "relative to its parent%s. " % (
                        "; rotors (more than a full turn: %s) on their own panels, below the hinges"
                        % ", ".join(j["name"] for j in rotors) if rotors and hinges else ""))
    if prismatic:
        caption += ("Prismatic joints: each child's position (m) and rate (m/s) along its sliding axis, "
                    "relative to its parent. ")
    if universal:
        caption += ("Universal joints (two-axis gimbals): the two gimbal angles (rad) and their rates, "
                    "the first axis (fixed in the parent) thick, the second (turning with the first "
                    "angle) thin. ")
    if spherical:
        caption += ("Spherical joints: the joint rotation q_J = q_offset^-1 q_NP^-1 q_NC computed from "
                    "the parent's and child's attitudes in each run, as its rotation angle |phi| and "
                    "its rotation vector phi (joint frame; |phi| <= pi), and the magnitude of the "
                    "child's angular velocity relative to the parent. ")
    return name, caption + "Colour tells the joints apart; the line style tells the runs apart."


def body_run_sections(bodies, runs):
    """Legend sections of a chart whose colour is the body and line style the run."""
    from matplotlib.lines import Line2D
    return [("body (colour)", [Line2D([], [], color=JOINT_COLOURS[i % len(JOINT_COLOURS)], lw=2.2)
                               for i in range(len(bodies))], bodies),
            ("run (line style)", [Line2D([], [], color="0.3", linestyle=r.dash) for r in runs],
             [r.label for r in runs])]


def chart_attitudes(scene, runs, out_dir, sid):
    """Flexible scenes (the paper's Fig. 11 for Example 2): every body's attitude as the three
    components of its rotation vector (log map of q_NB, rad, inertial axes), runs overlaid. For a
    motion in the x-z plane (Example 2) the y component is the attitude angle about y and the
    others stay zero."""
    system = scene.get("system", {})
    if not any(b.get("modes") for b in system.get("bodies", [])):
        return None
    bodies = [b["name"] for b in system.get("bodies", [])]
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
    drawn = False
    for bi, body in enumerate(bodies):
        colour = JOINT_COLOURS[bi % len(JOINT_COLOURS)]
        for r in runs:
            q = attitude(r, body)
            if q is None:
                continue
            phi = rotation_vector(q)
            for ci, ax in enumerate(axes):
                ax.plot(r.t, phi[:, ci], color=colour, linestyle=r.dash)
            drawn = True
    if not drawn:
        plt.close(fig)
        return None
    for ax, comp in zip(axes, ("x", "y", "z")):
        ax.set_ylabel("rotation about %s (rad)" % comp)
        rad_axis(ax, "rad")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time t (s)")
    outside_legend(fig, sections=body_run_sections(bodies, runs))
    figs = flexible_paper_figures(scene)
    fig.suptitle("Attitude of every body: rotation vector of q_NB in inertial axes%s"
                 % ("\n(the rotation about y is the attitude angle of the paper's Fig. %s)" % figs[0]
                    if figs else ""))
    name = finish(fig, "%s-attitudes.png" % sid, out_dir)
    return name, ("Each body's attitude as a rotation vector (axis times angle, rad; degrees on the "
                  "right axis) in the inertial frame, every run overlaid (colour: body; line style: "
                  "run). In a motion confined to the x-z plane only the y component moves: it is "
                  "the attitude angle about y.")


def chart_modal(scene, runs, out_dir, sid):
    cols = []
    for b in scene.get("system", {}).get("bodies", []):
        for m in b.get("modes", []):
            cols.append(b["name"] + "." + m)
    if not cols:
        return None
    fig, ax = plt.subplots(figsize=(10, 4.2))
    for i, c in enumerate(cols):
        for r in runs:
            if r.has(c):
                ax.plot(r.t, r.col(c), color=JOINT_COLOURS[i % len(JOINT_COLOURS)], linestyle=r.dash)
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("modal coordinate (m)")
    ax.grid(True, alpha=0.3)
    from matplotlib.lines import Line2D
    outside_legend(fig, handles=[Line2D([], [], color=JOINT_COLOURS[i % len(JOINT_COLOURS)]) for i in range(len(cols))],
                   labels=cols, title="mode (colour)")
    figs = flexible_paper_figures(scene)
    ax.set_title("Elastic deformation: modal coordinates of the flexible bodies%s"
                 % (" (the paper's Fig. %s)" % figs[1] if figs else ""))
    name = finish(fig, "%s-modal.png" % sid, out_dir)
    return name, ("Modal coordinates (m, in the scene's mode normalisation) of each flexible body, "
                  "every run overlaid (colour: mode; line style: run).")


def padded_limits(values):
    lo, hi = float(np.min(values)), float(np.max(values))
    mid = 0.5 * (lo + hi)
    pad = max(0.08 * (hi - lo), 1e-3 * abs(mid), 1e-12)
    return mid - max(pad, 0.5 * (hi - lo) + pad), mid + max(pad, 0.5 * (hi - lo) + pad)


def chart_H_E(scene, runs, out_dir, sid):
    if not any(r.has("H") for r in runs):
        return None
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.2), sharex=True)
    for ax, x, unit, what in ((axes[0], "H", "kg m^2/s", "angular momentum about the system CM"),
                              (axes[1], "E", "J", "mechanical energy (kinetic + elastic + gravity potential)")):
        values = [r.col(x) for r in runs if r.has(x)]
        plot_lines(ax, runs, x)
        if values:
            ax.set_ylim(*padded_limits(np.concatenate(values)))
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_ylabel("%s (%s)" % (x, unit))
        ax.set_title("%s: %s" % (x, what), fontsize="medium")
        ax.grid(True, alpha=0.3)
    outside_legend(fig, axes[0], title="run")
    axes[-1].set_xlabel("time t (s)")
    figs = paper_figures(scene)
    fig.suptitle("Magnitude of the total angular momentum H and total energy E against time%s"
                 % ("\n(H is the quantity of the paper's Fig. %s)" % figs[2] if figs else ""))
    name = finish(fig, "%s-H-E.png" % sid, out_dir)
    return name, ("H (kg m^2/s) and E (J) of every run. The vertical range is at least 0.1 % of "
                  "the value, so a conserved quantity shows as a flat line; its drift is in the "
                  "drift chart below on a log scale.")


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
    present = {c["group"] for c in scene.get("checks", [])}
    groups = [g for g in scene.get("group_order", []) if g in present and
              g in ("w", "attitude", "rate", "angle", "position", "modal", "torque", "load", "H", "E", "extra")]
    palette = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    colours = {g: palette[i % len(palette)] for i, g in enumerate(groups)}
    n = len(pairs)
    cols = 1 if n == 1 else 2
    rows_ = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows_, cols, figsize=(10 if cols == 1 else 13, 3.4 * rows_ + 1.0),
                             squeeze=False, sharey=True)
    drawn = set()
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
                drawn.add(g)
        ax.axhline(1.0, color="red", linestyle="--", linewidth=1.2)
        ax.set_title("%s compared with %s" % (a, b), fontsize="medium")
        ax.set_xlabel("time t (s)")
        ax.set_ylabel("|a - b| / (atol + rtol max|b|)")
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], color=colours[g], lw=1.6) for g in groups if g in drawn]
    labels = [GROUP_TITLES.get(g, g) for g in groups if g in drawn]
    handles.append(Line2D([], [], color="red", linestyle="--", lw=1.2))
    labels.append("tolerance (= 1)")
    outside_legend(fig, handles=handles, labels=labels, title="kind of quantity")
    fig.suptitle("Pairwise differences between runs, as a fraction of the tolerance (log scale)\n"
                 "each line: the largest over the quantities of that kind; above the red line fails")
    name = finish(fig, "%s-differences.png" % sid, out_dir)
    return name, ("For every pair of runs (a compared with the reference b) and every kind of "
                  "quantity, the largest normalised difference |a(t) - b(t)| / (atol + rtol "
                  "max|b|) at each output time; attitudes use the rotation angle between the two "
                  "attitudes. A check passes when its curve stays at or below 1 (red dashed line) "
                  "for the whole run. Exact agreement is drawn at 1e-17.")


def _poly_integral(piece, u, v, points):
    """The integral over [u, v] of the polynomial through the last `points` samples of piece."""
    p = piece[len(piece) - points:]
    t0, f0 = p[0]
    U, V = u - t0, v - t0
    r = f0 * (V - U)
    if points >= 2:
        t1, f1 = p[1]
        d1 = (f1 - f0) / (t1 - t0)
        r += d1 * (V * V - U * U) / 2
        if points >= 3:
            t2, f2 = p[2]
            d2 = ((f2 - f1) / (t2 - t1) - d1) / (t2 - t0)
            r += d2 * ((V ** 3 - U ** 3) / 3 - (t1 - t0) * (V * V - U * U) / 2)
    return r


def balance_integral(t, rate, breakpoints=()):
    """The integral of rate from t[0] on the output times, by the harness's rule for a balance
    (harness/compare.cpp, PiecewiseQuadrature): pieces apart at the breakpoints, each interval by
    the quadratic through it and the sample before, provisional values corrected as samples come."""
    breaks = sorted(b for b in breakpoints if b > t[0])
    W = np.zeros(len(t))
    w = 0.0
    piece, count, pending, tb, prov, first_trap, nb = [(t[0], rate[0])], 1, False, 0.0, 0.0, 0.0, 0
    for k in range(1, len(t)):
        tk, fk = float(t[k]), float(rate[k])
        t_prev = piece[-1][0]
        inside = []
        while nb < len(breaks) and breaks[nb] <= tk:
            if breaks[nb] > t_prev:
                inside.append(breaks[nb])
            nb += 1
        if inside:
            w += _poly_integral(piece, t_prev, inside[0], len(piece))
            w += fk * (inside[-1] - inside[0])
            prov = fk * (tk - inside[-1])
            w += prov
            pending, tb, piece, count = True, inside[-1], [(tk, fk)], 1
            W[k] = w
            continue
        piece.append((tk, fk))
        piece = piece[-3:]
        count += 1
        m = len(piece)
        trap = (tk - t_prev) / 2 * (piece[m - 2][1] + fk)
        if m == 2:
            w += trap
            first_trap = trap
        else:
            w += _poly_integral(piece, t_prev, tk, 3)
            if count == 3:
                a = piece[1][0] - piece[0][0]
                w += _poly_integral(piece, piece[0][0], piece[0][0] + a, 3) - first_trap
        if pending and count <= 3:
            better = _poly_integral(piece, tb, piece[0 if count == 3 else m - 2][0], min(m, 3))
            w += better - prov
            prov = better
        if count >= 3:
            pending = False
        W[k] = w
    return W


def chart_drift(scene, runs, out_dir, sid):
    engines = [r for r in runs if r.info.get("engine") != "analytic" and r.has("H")]
    if not engines:
        return None
    checks = {(c["quantity"], c["a"]): c for c in scene.get("checks", [])
              if c["group"].endswith(".drift") or c["group"].endswith(".balance")}
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.4), sharex=True)
    reasons = {"H": scene.get("momentum_not_conserved", ""), "E": scene.get("energy_not_conserved", ""),
               "J": scene.get("jacobi_not_conserved", "")}
    # On an orbit E changes as the gravity-gradient potential turns with the orbit frame: its panel
    # shows the Jacobi integral J, the conserved one (docs/environment.md), when nothing else changes it.
    orbit = bool(scene.get("orbit")) and all(r.has("J") for r in engines)
    second = "J" if orbit else "E"
    for ax, x in zip(axes, ("H", second)):
        if x == "J" and reasons["J"]:
            ax.text(0.5, 0.5, "J is not conserved: %s" % reasons["J"].replace("scene has ", "the scene has "),
                    ha="center", va="center", transform=ax.transAxes)
            ax.set_title("the Jacobi integral J", fontsize="medium")
            continue
        balanced = bool(reasons[x])
        names = (["E"], ["P"]) if x == "E" else (["Hx", "Hy", "Hz"], ["Mx", "My", "Mz"])
        relative = True
        for r in engines:
            if balanced:
                if not all(r.has(n) for n in names[0] + names[1]):
                    continue
                X = np.stack([r.col(n) for n in names[0]], axis=1)
                W = np.stack([balance_integral(r.t, r.col(n), scene.get("breakpoints", [])) for n in names[1]],
                             axis=1)
                dev = np.linalg.norm(X - X[0] - W, axis=1)
                x0 = max(np.max(np.linalg.norm(X, axis=1)), 0.0)
                c = checks.get((x + ".balance", r.label))
            else:
                if not r.has(x):
                    continue
                v = r.col(x)
                x0 = abs(v[0])
                dev = np.abs(v - v[0])
                c = checks.get((x + ".drift", r.label))
            scale = c["scale"] if balanced and c and c.get("scale") else x0
            relative = relative and scale > 0
            d = dev / (scale if scale > 0 else 1.0)
            ax.semilogy(r.t, np.maximum(d, TINY), label=r.label, **{k: s for k, s in r.style.items() if k != "alpha"})
            if c and c["status"] in ("PASS", "FAIL") and c["bound"]:
                ax.axhline(c["bound"] / (scale if scale > 0 else 1.0), color=r.style["color"],
                           linestyle="--", linewidth=0.9, alpha=0.7)
        unit = "" if relative else (" (kg m^2/s)" if x == "H" else " (J)")
        if balanced:
            what = "|E(t) - E(0) - W(t)|" if x == "E" else "|H(t) - H(0) - integral of M|"
            ax.set_ylabel(what + (" / scale" if relative else unit))
            title = ("balance of %s (not conserved: %s) against the integral of its %s"
                     % (x, reasons[x].replace("scene has ", ""), "power P" if x == "E" else "external moment M"))
        else:
            ax.set_ylabel(("|%s(t) - %s(0)| / |%s(0)|" % (x, x, x)) if relative else ("|%s(t) - %s(0)|%s" % (x, x, unit)))
            title = "drift of %s from its initial value" % x
            if x == "J":
                title = "drift of the Jacobi integral J = E - w_NO . H_O (E itself changes on an orbit)"
        ax.set_title(title, fontsize="medium")
        ax.grid(True, which="both", alpha=0.3)
    outside_legend(fig, axes[0], title="engine")
    axes[-1].set_xlabel("time t (s)")
    fig.suptitle("Conservation and balance of H and %s of each engine (log scale)\n" % second +
                 "dashed lines: each engine's check bound (drift: atol + rtol |X(0)|; balance: see the pass rule)")
    name = finish(fig, "%s-drift.png" % sid, out_dir)
    return name, ("Where the scene conserves them: the relative drift |X(t) - X(0)| / |X(0)| of the "
                  "angular momentum H and the energy E of each engine. Where it does not (dampers, "
                  "motors, prescribed joints, external torques): the balance X(t) - X(0) - W(t), W "
                  "the integral of the engine's own power P (for E) or external moment M about the "
                  "system CM (for H, as a vector), relative to the check's scale. Either measures "
                  "integration and formulation error; a load whose power is wrong in one engine's "
                  "equations of motion shows as that engine's balance growing.")


def chart_orbit(scene, runs, out_dir, sid):
    """Orbit scenes (issue 28): every body's attitude relative to the orbit frame (LVLH roll, pitch,
    yaw), runs overlaid, and the Jacobi integral's drift on a log scale."""
    if not scene.get("orbit"):
        return None
    engines = [r for r in runs if r.info.get("engine") != "analytic"]
    bodies = [b["name"] for b in scene.get("system", {}).get("bodies", [])]
    bodies = [b for b in bodies if any(r.has(b + ".pitch") for r in engines)]
    if not bodies:
        return None
    fig, axes = plt.subplots(4, 1, figsize=(10, 9.5), sharex=True)
    for bi, body in enumerate(bodies):
        colour = JOINT_COLOURS[bi % len(JOINT_COLOURS)]
        for r in engines:
            for ax, angle in zip(axes[:3], ("roll", "pitch", "yaw")):
                if r.has(body + "." + angle):
                    ax.plot(r.t, r.col(body + "." + angle), color=colour, linestyle=r.dash)
    for ax, angle, about in zip(axes[:3], ("roll", "pitch", "yaw"),
                                ("o1, along-track", "o2, the negative orbit normal", "o3, nadir")):
        ax.set_ylabel("%s (rad)\nabout %s" % (angle, about))
        rad_axis(ax, "rad")
        ax.grid(True, alpha=0.3)
    checks = {c["a"]: c for c in scene.get("checks", []) if c["quantity"] == "J.drift"}
    ax = axes[3]
    for r in engines:
        if not r.has("J"):
            continue
        J = r.col("J")
        scale = abs(J[0]) if abs(J[0]) > 0 else 1.0
        ax.semilogy(r.t, np.maximum(np.abs(J - J[0]) / scale, TINY), label=r.label,
                    **{k: s for k, s in r.style.items() if k != "alpha"})
        c = checks.get(r.label)
        if c and c["status"] in ("PASS", "FAIL") and c["bound"]:
            ax.axhline(c["bound"] / scale, color=r.style["color"], linestyle="--", linewidth=0.9, alpha=0.7)
    ax.set_ylabel("|J(t) - J(0)| / |J(0)|")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(title="engine (J)", fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set_xlabel("time t (s)")
    outside_legend(fig, sections=body_run_sections(bodies, engines))
    fig.suptitle("Attitude relative to the orbit frame (LVLH: R_OB = Rz(yaw) Ry(pitch) Rx(roll))\n"
                 "and the drift of the Jacobi integral J (log scale; dashed: each engine's check bound)")
    name = finish(fig, "%s-orbit.png" % sid, out_dir)
    return name, ("Each body's roll, pitch and yaw relative to the local orbit frame (x along-track, y "
                  "the negative orbit normal, z nadir; docs/environment.md), every engine overlaid "
                  "(colour: body; line style: engine), and the relative drift of each engine's Jacobi "
                  "integral J = E - w_NO . H_O, which a circular orbit conserves where nothing else "
                  "adds or removes energy.")


def _quat_rotate_inverse(q, v):
    """R(q)^T v for a unit quaternion q = (w, x, y, z), scalar first."""
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return R.T @ np.asarray(v, dtype=float)


def _applied_torque(joint, run, t):
    """A revolute joint's own torque about its axis from the scene: -k (angle - neutral) - c rate +
    motor(t) (docs/conventions.md "Loads"); a prescribed one's: its .torque column."""
    name = joint["name"]
    if run.has(name + ".torque"):
        return run.col(name + ".torque")
    angle, rate = run.col(name + ".angle"), run.col(name + ".rate")
    tau = (-joint.get("stiffness_N_m_rad", 0.0) * (angle - joint.get("neutral_angle_rad", 0.0))
           - joint.get("damping_N_m_s_rad", 0.0) * rate)
    motor = np.zeros_like(t)
    for step in joint.get("motor_N_m", []):
        motor = np.where(t >= step["from_t"], step["value"], motor)
    return tau + motor


def chart_loads(scene, runs, out_dir, sid):
    """One row per joint (at most 8, the most loaded first): the magnitude of the force and of the
    moment about the joint point that the parent exerts on the child, every engine overlaid; for a
    revolute joint also the moment about its axis beside the joint's own torque from the scene."""
    engines = [r for r in runs if r.info.get("engine") != "analytic"]
    joints = []
    for r in engines[:1]:
        for c in r.columns:
            if c.endswith(".Fx"):
                joints.append(c[:-3])
    if not joints or not engines:
        return None
    scene_joints = {j["name"]: j for j in scene.get("system", {}).get("joints", [])}

    def magnitude(r, j, q):
        return np.sqrt(sum(r.col("%s.%s%s" % (j, q, a)) ** 2 for a in "xyz"))

    def peak(j):
        r = engines[0]
        return float(np.max(magnitude(r, j, "M"))) + float(np.max(magnitude(r, j, "F")))
    shown = sorted(joints, key=peak, reverse=True)[:8]
    shown.sort(key=joints.index)
    axial = {j for j in shown if scene_joints.get(j, {}).get("type") == "revolute" and "axis" in scene_joints[j]}
    ncols = 3 if axial else 2
    fig, axes = plt.subplots(len(shown), ncols, figsize=(5 * ncols, 1.9 * len(shown) + 1.2), sharex=True,
                             squeeze=False)
    for row, j in zip(axes, shown):
        for ax, q, unit in ((row[0], "F", "N"), (row[1], "M", "N m")):
            for r in engines:
                if all(r.has("%s.%s%s" % (j, q, a)) for a in "xyz"):
                    ax.plot(r.t, magnitude(r, j, q), label=r.label, **r.style)
            ax.set_ylabel("|%s| (%s)" % (q, unit))
            ax.set_title("%s: %s" % (j, "force on the child" if q == "F" else "moment about the joint point"),
                         fontsize="small")
            ax.grid(True, alpha=0.3)
        if ncols == 3:
            ax = row[2]
            if j not in axial:
                ax.set_visible(False)
                continue
            J = scene_joints[j]
            # The axis in the child frame: the joint's rotation leaves it fixed, so it is the offset's
            # R_PJ0^T axis_P (a child attached at a flexible node turns it further by the node's slope).
            a_C = _quat_rotate_inverse(J.get("orientation_offset_q", [1, 0, 0, 0]), J["axis"])
            for r in engines:
                if all(r.has("%s.M%s" % (j, c)) for c in "xyz"):
                    M = np.stack([r.col("%s.M%s" % (j, c)) for c in "xyz"], axis=1)
                    ax.plot(r.t, M @ a_C, label=r.label, **r.style)
            if all(engines[0].has(j + c) for c in (".angle", ".rate")):
                ax.plot(engines[0].t, _applied_torque(J, engines[0], engines[0].t), color="black",
                        linestyle=(0, (1, 3)), linewidth=2.2, alpha=0.6, label="joint torque (scene)")
            ax.set_ylabel("M . axis (N m)")
            ax.set_title("%s: moment about its axis, and its own torque" % j, fontsize="small")
            ax.grid(True, alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time t (s)")
    handles, labels = [], []
    for ax in axes.flat:
        if ax.get_visible():
            for h, l in zip(*ax.get_legend_handles_labels()):
                if l not in labels:
                    handles.append(h)
                    labels.append(l)
    outside_legend(fig, handles=handles, labels=labels, title="engine (and scene)")
    more = "" if len(shown) == len(joints) else " (the %d most loaded of %d joints)" % (len(shown), len(joints))
    fig.suptitle("Joint loads from every engine%s\nthe parent on the child, through the joint" % more)
    name = finish(fig, "%s-loads.png" % sid, out_dir)
    return name, ("Each joint's load as each engine computes it its own way (newton-euler from its "
                  "constraint multipliers, kane and lagrange from their own accelerations): the "
                  "force F and the moment M about the joint point that the parent exerts on the "
                  "child (constraint reaction plus the joint's spring, damper, motor or drive; "
                  "components in the child's frame in the CSV columns <joint>.Fx ... .Mz). For a "
                  "revolute joint the third panel is M along the joint's axis beside the torque "
                  "the scene gives the joint (spring, damper and motor from the first run's angle "
                  "and rate; a prescribed joint's drive torque): they must coincide, since the "
                  "constraint carries no moment about the free axis. Overlaid lines that coincide "
                  "are the engines agreeing; the harness compares every component (group 'load').")


def chart_converge(scene, out_dir, sid):
    """`crossdyn converge` (verify runs it on flexible scenes): every model's largest change
    against the full model, relative to each quantity's scale, on a log scale; the line is the
    accuracy asked (--accuracy). Returns (file name, caption) or None."""
    conv = scene.get("converge")
    if not conv or len(conv.get("models", [])) < 2:
        return None
    models = [m for m in conv["models"] if not m.get("full")]
    labels = [m["label"] for m in models]
    accuracy = conv.get("accuracy", 1e-3)
    values = [m["worst_relative"] if m.get("worst_relative") is not None else float("inf")
              for m in models]
    finite = [v for v in values if np.isfinite(v) and v > 0]
    top = max(finite + [10.0 * accuracy]) * 10
    shown = [top if not np.isfinite(v) else max(v, TINY) for v in values]
    colours = ["#2ca02c" if m["passed"] else "#d62728" for m in models]
    hatches = ["//" if m.get("slices") else "" for m in models]
    fig, ax = plt.subplots(figsize=(10, 0.42 * len(models) + 1.6))
    y = np.arange(len(models))
    bars = ax.barh(y, shown, color=colours)
    for b, h in zip(bars, hatches):
        b.set_hatch(h)
    ax.set_xscale("log")
    ax.axvline(accuracy, color="0.2", linestyle="--", lw=1.2)
    ax.set_yticks(y)
    ax.set_yticklabels(labels, fontsize="small")
    ax.invert_yaxis()
    ax.set_xlabel("largest change against the full model, relative to the quantity's scale "
                  "(log scale; <= %s is within)" % format(accuracy, "g"))
    ax.grid(True, axis="x", alpha=0.3)
    from matplotlib.patches import Patch
    outside_legend(fig, handles=[Patch(color="#2ca02c"), Patch(color="#d62728"),
                                 Patch(facecolor="white", edgecolor="0.3", hatch="//")],
                   labels=["within the accuracy", "changes the answer", "slicing row"],
                   title="model")
    ax.set_title("Model no more than the scene needs: smallest model %s" % conv.get("smallest", ""),
                 fontsize="medium")
    name = finish(fig, "%s-converge.png" % sid, out_dir)
    return name, ("Each model with fewer modes (and each beam re-sliced with half and twice its "
                  "slices, hatched) run by %s and compared with the full model on every quantity; "
                  "the bar is the largest change relative to that quantity's scale (the size of its "
                  "kind of motion in the full model; attitudes in rad; zero is drawn at 1e-17). "
                  "Green stays within the accuracy %s (the dashed line)."
                  % (conv.get("engine", "kane"), format(accuracy, "g")))


# ---- `crossdyn study`: speed against accuracy, and the scaling of the right-hand side ----

# Colour: the integrator; marker and line style: the engine (study charts).
STUDY_COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
                 "tab:pink", "tab:olive", "tab:cyan", "0.3"]
STUDY_MARKERS = {"kane": "o", "lagrange": "s", "newton-euler": "^"}
STUDY_DASHES = {"kane": "-", "lagrange": "--", "newton-euler": ":"}


def _study_look(engine, integrator, integrators, engines):
    colour = STUDY_COLOURS[integrators.index(integrator) % len(STUDY_COLOURS)]
    k = engines.index(engine)
    return dict(color=colour, marker=STUDY_MARKERS.get(engine, "dvpx"[k % 4]),
                linestyle=STUDY_DASHES.get(engine, "-."), linewidth=1.3, markersize=4.5)


def chart_study(scene, out_dir):
    """Work-precision chart of one scene: end-state error (left) and history error (right) against
    the median CPU time of the integration, log-log; one line per engine x integrator through its
    tolerances (or rk4 steps); the Pareto front marked. Returns (file name, caption) or None."""
    rows = [r for r in scene.get("rows", []) if r.get("ok") and r.get("cpu_median")]
    if not rows:
        return None
    engines = list(dict.fromkeys(r["engine"] for r in scene["rows"]))
    integrators = list(dict.fromkeys(r["integrator"] for r in scene["rows"]))
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 5.2), sharey=False)
    handles, labels = [], []
    for ax, key, front_key, title in ((axes[0], "end_error", "front_end", "end-state error"),
                                      (axes[1], "history_error", "front_history", "history error")):
        for engine in engines:
            for integ in integrators:
                line = [r for r in rows if r["engine"] == engine and r["integrator"] == integ
                        and r.get(key) is not None]
                if not line:
                    continue
                x = [1e3 * r["cpu_median"] for r in line]
                y = [max(r[key], TINY) for r in line]
                h, = ax.plot(x, y, **_study_look(engine, integ, integrators, engines))
                if ax is axes[0]:
                    handles.append(h)
                    labels.append("%s + %s" % (engine, integ))
        front = sorted((1e3 * r["cpu_median"], max(r[key], TINY)) for r in rows
                       if r.get(front_key) and r.get(key) is not None)
        if front:
            fx, fy = zip(*front)
            hf, = ax.step(fx, fy, where="post", color="black", linewidth=2.2, alpha=0.35, zorder=0)
            ax.plot(fx, fy, linestyle="none", marker="o", markersize=11, markerfacecolor="none",
                    markeredgecolor="black", markeredgewidth=1.2)
            if ax is axes[0]:
                handles.append(hf)
                labels.append("Pareto front (circled)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU time of the integration, ms (median)")
        ax.set_ylabel(title + " (relative; rad for angles)")
        ax.set_title("%s: %s against CPU time" % (scene.get("scene"), title), fontsize="medium")
        ax.grid(True, which="both", alpha=0.25)
    outside_legend(fig, handles=handles, labels=labels, title="engine + integrator")
    name = finish(fig, "%s-study.png" % scene["id"], out_dir)
    return name, ("Speed against accuracy on %s: each line is one engine with one integrator, its "
                  "points the tolerances (rk4: the steps) from loose (left) to tight; colour is the "
                  "integrator, marker and dash the engine. Left: error of the end state; right: the "
                  "largest error over every output time; both against the %s. The thick grey step "
                  "line and the circles are the Pareto front: no configuration is both faster and "
                  "more accurate than a circled one (errors below the reference's own accuracy count as "
                  "equal). Errors of exactly 0 are drawn at 1e-17."
                  % (scene.get("scene"), "analytic solution" if scene["reference"]["kind"] == "analytic"
                     else "engines' reference"))


def chart_scaling(scaling, out_dir):
    """Right-hand-side cost against chain length N (log-log), one line per engine, the fitted
    exponent in the legend. Returns (file name, caption) or None."""
    lines = scaling.get("lines", [])
    if not lines:
        return None
    fig, ax = plt.subplots(figsize=(10, 5.2))
    for k, line in enumerate(lines):
        pts = [p for p in line["points"] if p.get("ok") and p.get("seconds_per_call")]
        if not pts:
            continue
        x = [p["links"] for p in pts]
        y = [1e6 * p["seconds_per_call"] for p in pts]
        e = line.get("exponent")
        label = "%s: N^%s" % (line["engine"], "%.2f" % e if e is not None else "?")
        style = dict(STYLES.get(line["engine"], {}))
        style.update(marker=STUDY_MARKERS.get(line["engine"], "d"), markersize=5)
        style.setdefault("color", STUDY_COLOURS[k % len(STUDY_COLOURS)])
        ax.plot(x, y, label=label, **style)
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("links N (chainN, docs/scenarios.md Scene 3)")
    ax.set_ylabel("CPU per right-hand side, us (median)")
    ax.set_title("Right-hand-side cost against chain length", fontsize="medium")
    ax.grid(True, which="both", alpha=0.25)
    outside_legend(fig, ax, title="engine: fitted cost")
    name = finish(fig, "scaling.png", out_dir)
    return name, ("Median CPU time of one right-hand side of each engine on chainN at its initial "
                  "state, against N (log-log). The exponent is the least-squares slope of log cost "
                  "against log N over the upper half of N.")


def chart_conditioning(scaling, out_dir):
    """The conditioning of each engine's linear solve on chainN (harness/conditioning.hpp): left,
    the condition number kappa against N; right, the deviation of its accelerations from the closest
    other engine's. Log-log, one line per engine. Returns (file name, caption) or None."""
    lines = [l for l in scaling.get("lines", [])
             if any(p.get("condition") is not None for p in l.get("points", []))]
    if not lines:
        return None
    fig, (ax_k, ax_d) = plt.subplots(1, 2, figsize=(11, 4.6))
    for k, line in enumerate(lines):
        style = dict(STYLES.get(line["engine"], {}))
        style.update(marker=STUDY_MARKERS.get(line["engine"], "d"), markersize=5)
        style.setdefault("color", STUDY_COLOURS[k % len(STUDY_COLOURS)])
        pts = [p for p in line["points"] if p.get("condition") is not None]
        e = line.get("condition_exponent")
        label = "%s: N^%s" % (line["engine"], "%.2f" % e if e is not None else "?")
        ax_k.plot([p["links"] for p in pts], [p["condition"] for p in pts], label=label, **style)
        dev = [p for p in line["points"] if p.get("accel_deviation") is not None]
        if dev:
            ax_d.plot([p["links"] for p in dev], [max(p["accel_deviation"], TINY) for p in dev],
                      **style)
    for ax in (ax_k, ax_d):
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("links N (chainN)")
        ax.grid(True, which="both", alpha=0.25)
    ax_k.set_ylabel("condition number sigma_max / sigma_min")
    ax_k.set_title("Conditioning of the linear solve", fontsize="medium")
    ax_d.set_ylabel("difference from the closest other engine (relative)")
    ax_d.set_title("What it costs: accelerations' deviation", fontsize="medium")
    outside_legend(fig, ax_k, title="engine: fitted growth")
    name = finish(fig, "conditioning.png", out_dir)
    return name, ("Left: the condition number of the linear system each engine solves for its "
                  "accelerations on chainN at its initial state (a backward-stable solve may lose "
                  "up to log10 of it in digits). Right: the largest difference of each engine's "
                  "accelerations from those of the closest other engine, relative to the largest "
                  "of that kind (exact agreement drawn at 1e-17): the digits actually lost.")


CHARTS = [chart_base_w, chart_joints, chart_attitudes, chart_orbit, chart_modal, chart_H_E, chart_loads,
          chart_differences, chart_drift]

__all__ = ["CHARTS", "GROUP_TITLES", "DASHES", "gfmt"]
