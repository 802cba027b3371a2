"""Pictures of a scene as crossdyn read it, from the geometry document that crossdyn writes
(harness/scene_geometry.cpp, `crossdyn draw`, the report's data/<scene>/geometry.json).

Geometry document (JSON, "format": "crossdyn scene geometry", "version": 1). Vectors are lists of 3
numbers, matrices lists of 3 rows; SI units; frames as in core/system.hpp:

    bodies[i]   name, mass_kg, is_base, flexible,
                shape: {type: "box", R_BX (columns: box axes in B), size_m (sides along them)},
                nodes: [{name, p_BoN_B}]           (a flexible body's nodes, undeformed; else [])
    joints[j]   name, type (free|revolute|spherical|fixed), dof, prescribed, parent (-1: N), child,
                parent_node, child_node (-1: rigid attachment),
                parent_point_P_m, child_point_C_m, R_PJ0 (offset), has_offset,
                revolute: axis_P, axis_C, initial_angle_rad, initial_rate_rad_s;
                free: initial_w_NB_B_rad_s
    initial     one configuration at t = 0, in N as the scene places it
    motion      {engine, state (ok|failed|not run), note, duration_s, frames: [configuration...]}
                the later configurations, each with the system CM at N's origin
    configuration = {t, centred_at_cm, p_NoScm_N,
                     bodies: [{p_NoBo_N, R_NB, nodes_N (flexible bodies: the nodes, deformed)}],
                     joints: [{p_NoJ_N_parent, p_NoJ_N_child, gap_m, axis_N_parent, axis_N_child,
                               axis_mismatch_rad, phi_J_rad}]}
    orbit       (a scene on an orbit) {what}; every configuration then has R_NO, the orbit frame
                O (LVLH: o1 along-track, o2 the negative orbit normal, o3 nadir) at its time
    warnings    the scene's warnings as crossdyn printed them (harness/scene_warnings.hpp):
                [{code, subject, line (null: none), column, message}]; the picture shows these and
                makes none of its own, so that it and the terminal always say the same

New kinds of things are added as new keys (a body's node displacements per configuration, a
prescribed joint's flag), so a reader ignores what it does not know.

Everything here is drawing: the kinematics (where each body and joint point is) was done by
crossdyn and is tested there (tests/harness/test_scene_geometry.cpp).
"""

import json
import math

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon
from mpl_toolkits.mplot3d import proj3d
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from .common import gfmt, png_bytes

AXIS_COLOURS = ("#e41a1c", "#1a9a1a", "#1f4fd6")  # body axes x red, y green, z blue
BODY_COLOURS = ["#9a9a9a", "#ff9f1c", "#9467bd", "#17becf", "#8c564b", "#e377c2", "#bcbd22",
                "#6b8e23", "#4682b4", "#d2691e"]  # base grey, then the others
AXIS_ARROW = "#5b0f8a"   # revolute axes
SLIDE_ARROW = "#0a6b3d"  # prismatic axes
SWING = "#111111"        # where the child's CM goes for a positive angle
MISMATCH = "#ff0000"     # joint points or axes that should coincide but do not; scene warnings
SYMMETRY = "#b35900"     # the mirror-axes warning: mirror-image panels that do not move as such
SPIN = "#d1007f"         # the base's initial angular velocity
N_COLOUR = "0.35"
ORBIT = "#0b7a75"        # the orbit frame O (LVLH): along-track, -orbit normal, nadir
VIEW = dict(elev=22, azim=-60)
FACES = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
# The three projections drawn beside the 3-D view: (title, right axis, up axis); the viewer looks
# along -(right x up), so the out-of-page direction is right x up.
PROJECTIONS = [("top: looking along -N z", 0, 1), ("front: looking along +N y", 0, 2),
               ("side: looking along -N x", 1, 2)]


def load(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def colours(geom):
    out, k = [], 0
    for b in geom["bodies"]:
        if b.get("is_base"):
            out.append(BODY_COLOURS[0])
        else:
            out.append(BODY_COLOURS[1 + k % (len(BODY_COLOURS) - 1)])
            k += 1
    return out


def darker(colour, f=0.6):
    r, g, b = matplotlib.colors.to_rgb(colour)
    return (r * f, g * f, b * f)


def rodrigues(axis, angle):
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def corners(body, pose, min_side=0.0):
    """The 8 corners of a body's equivalent box in N (index bits: x', y', z' sign)."""
    shape = body["shape"]
    size = np.maximum(np.asarray(shape["size_m"], float), min_side)
    R = np.asarray(pose["R_NB"], float) @ np.asarray(shape["R_BX"], float)
    p = np.asarray(pose["p_NoBo_N"], float)
    out = []
    for k in range(8):
        s = np.array([1 if k & 4 else -1, 1 if k & 2 else -1, 1 if k & 1 else -1]) * 0.5 * size
        out.append(p + R @ s)
    return np.array(out)


def inside_box(point, body, pose, margin=0.0):
    shape = body["shape"]
    R = np.asarray(pose["R_NB"], float) @ np.asarray(shape["R_BX"], float)
    local = R.T @ (np.asarray(point, float) - np.asarray(pose["p_NoBo_N"], float))
    return bool(np.all(np.abs(local) < 0.5 * np.asarray(shape["size_m"], float) - margin))


def frame_points(geom, frame):
    pts = []
    for b, pose in zip(geom["bodies"], frame["bodies"]):
        pts.extend(corners(b, pose))
    for j in frame["joints"]:
        pts.append(j["p_NoJ_N_parent"])
        pts.append(j["p_NoJ_N_child"])
    return np.array(pts, float)


def limits(points, include_origin):
    """Axis limits around the points (and N's origin): equal scale on every axis, each range at
    least 35 % of the longest so that a flat or long scene still has room for its labels.
    Returns (lo, hi, half) with half = half the longest range."""
    pts = np.vstack([points, np.zeros((1, 3))]) if include_origin else np.asarray(points, float)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = max(float(np.max(hi - lo)), 1e-3)
    centre = 0.5 * (lo + hi)
    half_ranges = np.maximum(0.5 * (hi - lo), 0.35 * 0.5 * span) + 0.10 * span
    return centre - half_ranges, centre + half_ranges, float(np.max(half_ranges))


def scene_limits(geom, frames):
    """Limits for a set of configurations: N's origin included unless it is far off the scene."""
    pts = np.vstack([frame_points(geom, f) for f in frames])
    lo, hi, half = limits(pts, include_origin=True)
    lo2, hi2, half2 = limits(pts, include_origin=False)
    return (lo2, hi2, half2) if half2 < 0.4 * half else (lo, hi, half)


def hull2d(points):
    """Convex hull of 2-D points (Andrew's monotone chain), counter-clockwise."""
    pts = sorted(set(map(tuple, np.round(points, 12))))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


# ----------------------------------------------------------------------------------------------
# Painters: the same drawing on a 3-D axes or on a 2-D projection.


class Painter3D:
    def __init__(self, ax):
        self.ax = ax

    def project(self, p):
        x2, y2, _ = proj3d.proj_transform(p[0], p[1], p[2], self.ax.get_proj())
        return np.array([x2, y2])

    def boxes(self, boxes, colours_, alphas):
        # One collection, so that matplotlib sorts all the faces by depth together.
        faces, fc, ec = [], [], []
        for c, colour, alpha in zip(boxes, colours_, alphas):
            for f in FACES:
                faces.append([c[k] for k in f])
                fc.append(matplotlib.colors.to_rgba(colour, alpha))
                ec.append(matplotlib.colors.to_rgba(darker(colour), 0.9))
        self.ax.add_collection3d(Poly3DCollection(faces, facecolors=fc, edgecolors=ec, linewidths=0.8,
                                                  zorder=1))

    def line(self, pts, **kw):
        pts = np.asarray(pts, float)
        self.ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], zorder=3, **kw)

    def arrow(self, start, vector, colour, lw=1.8, head=0.22, symbol_at=None):
        """Returns True when the arrow was drawn as a symbol (never in 3-D); symbol_at: where to put
        the symbol of an arrow along the line of sight in a projection (None: leave it out)."""
        self.ax.quiver(*start, *vector, color=colour, linewidth=lw, arrow_length_ratio=head, zorder=4)
        return False

    def marker(self, p, **kw):
        kw.setdefault("zorder", 6)
        self.ax.scatter(*p, depthshade=False, **kw)

    def text(self, p, s, **kw):
        self.ax.text(*p, s, zorder=15, **kw)

    def ball(self, p, r, colour):
        u, v = np.mgrid[0:2 * np.pi:14j, 0:np.pi:8j]
        self.ax.plot_surface(p[0] + r * np.cos(u) * np.sin(v), p[1] + r * np.sin(u) * np.sin(v),
                             p[2] + r * np.cos(v), color=colour, alpha=0.35, linewidth=0, shade=True,
                             zorder=5)


class Painter2D:
    """An orthographic projection on the plane of N axes i (right) and j (up)."""

    def __init__(self, ax, i, j):
        self.ax, self.i, self.j = ax, i, j
        self.out = np.cross(np.eye(3)[i], np.eye(3)[j])  # towards the viewer

    def project(self, p):
        return np.array([p[self.i], p[self.j]])

    def boxes(self, boxes, colours_, alphas):
        for c, colour, alpha in zip(boxes, colours_, alphas):
            h = hull2d(np.array([self.project(p) for p in c]))
            if len(h) >= 3:
                self.ax.add_patch(Polygon(h, closed=True, facecolor=colour, edgecolor=darker(colour),
                                          linewidth=0.8, alpha=alpha, zorder=1))

    def line(self, pts, **kw):
        q = np.array([self.project(p) for p in pts])
        self.ax.plot(q[:, 0], q[:, 1], **kw)

    def arrow(self, start, vector, colour, lw=1.8, head=0.22, symbol_at=None):
        a, b = self.project(start), self.project(np.asarray(start) + np.asarray(vector))
        length = float(np.linalg.norm(vector))
        if np.linalg.norm(b - a) < 0.3 * length:
            if symbol_at is None:
                return False  # a body axis along the view: left out
            # Along the line of sight: a dot (pointing at the viewer) or a cross (away).
            at = self.project(symbol_at if symbol_at is not None else start)
            towards = np.dot(vector, self.out) > 0
            self.ax.plot(*at, marker="o", markersize=12, markerfacecolor="white", markeredgecolor=colour,
                         markeredgewidth=1.8, zorder=11)
            self.ax.plot(*at, marker="o" if towards else "x", markersize=3.5 if towards else 7,
                         color=colour, markeredgewidth=2.0, zorder=12)
            return True
        big = head > 0.5  # an arrowhead alone (the end of a swing arc)
        self.ax.annotate("", xy=b, xytext=a, arrowprops=dict(
            arrowstyle="-|>,head_length=%.2f,head_width=%.2f" % ((0.7, 0.35) if big else (0.45, 0.22)),
            mutation_scale=10, color=colour, lw=lw, shrinkA=0, shrinkB=0))
        return False

    def marker(self, p, s=20, color=None, marker="o", edgecolor=None, linewidth=None, facecolor=None,
               zorder=None):
        q = self.project(p)
        kw = dict(s=s * 0.6, marker=marker, linewidths=linewidth, zorder=zorder or 6)
        if facecolor is not None:
            kw["facecolors"] = facecolor
        elif color is not None:
            kw["c"] = [color] if not isinstance(color, str) else color
        if edgecolor is not None:
            kw["edgecolors"] = edgecolor
        self.ax.scatter(q[0], q[1], **kw)

    def text(self, p, s, **kw):
        q = self.project(p)
        self.ax.text(q[0], q[1], s, **kw)

    def ball(self, p, r, colour):
        self.ax.add_patch(Circle(self.project(p), r, facecolor=colour, alpha=0.35, edgecolor="0.3"))


# ----------------------------------------------------------------------------------------------
# Labels that avoid each other


class Labels:
    """Labels for 3-D points, placed after the drawing so that they do not overlap: each tries a
    few offsets around its point (screen space) and keeps the least crowded one."""

    def __init__(self):
        self.items = []

    def add(self, point, text, colour="black", size=8.5, weight="normal", priority=1):
        self.items.append((np.asarray(point, float), text, colour, size, weight, priority))

    def place(self, painter, fig, min_priority=-1):
        ax = painter.ax
        # Settles the axes' aspect and position (all that a full draw of the figure did here,
        # at a fraction of its cost: the limits are fixed by setup_2d/setup_3d).
        ax.apply_aspect()
        renderer = fig.canvas.get_renderer()
        items = [it for it in self.items if it[5] >= min_priority]
        anchors = [painter.project(p) for p, *_ in items]
        pix = [ax.transData.transform(a) for a in anchors]
        box = ax.bbox
        placed = []
        for i in sorted(range(len(items)), key=lambda i: -items[i][5]):
            _, text, colour, size, weight, _ = items[i]
            best = best_score = best_ext = None
            for radius in (8, 20, 34, 52, 72):
                for ang in (45, 135, -45, -135, 90, -90, 0, 180, 20, 160, -20, -160):
                    dx = radius * math.cos(math.radians(ang))
                    dy = radius * math.sin(math.radians(ang))
                    ha = "left" if dx > 1 else "right" if dx < -1 else "center"
                    va = "bottom" if dy > 1 else "top" if dy < -1 else "center"
                    t = ax.annotate(text, xy=anchors[i], xytext=(dx, dy), textcoords="offset points",
                                    fontsize=size, color=colour, weight=weight, ha=ha, va=va, zorder=20,
                                    bbox=dict(boxstyle="round,pad=0.12", fc="white", ec="none", alpha=0.8),
                                    arrowprops=dict(arrowstyle="-", lw=0.6, color=colour, shrinkA=0,
                                                    shrinkB=1) if radius > 8 else None,
                                    annotation_clip=False)
                    ext = t.get_window_extent(renderer)
                    score = 0.0
                    for other in placed:
                        ix = max(0.0, min(ext.x1, other.x1) - max(ext.x0, other.x0) + 3)
                        iy = max(0.0, min(ext.y1, other.y1) - max(ext.y0, other.y0) + 3)
                        score += ix * iy
                    for k, q in enumerate(pix):  # keep the other labelled points visible
                        if k != i and ext.x0 - 3 < q[0] < ext.x1 + 3 and ext.y0 - 3 < q[1] < ext.y1 + 3:
                            score += 60.0
                    outside = (max(0, box.x0 - ext.x0) + max(0, ext.x1 - box.x1) +
                               max(0, box.y0 - ext.y0) + max(0, ext.y1 - box.y1))
                    score += 80.0 * outside + 0.3 * radius
                    if best_score is None or score < best_score:
                        if best is not None:
                            best.remove()
                        best, best_score, best_ext = t, score, ext
                    else:
                        t.remove()
                if best_score <= 0.3 * radius + 1e-9:
                    break
            placed.append(best_ext)


# ----------------------------------------------------------------------------------------------
# One configuration


def positive_direction(frame, joint, js):
    """Unit direction (in N) in which a positive angle of a revolute joint moves the child's CM,
    or None when the CM is on the axis."""
    a = np.asarray(js["axis_N_parent"], float)
    r = np.asarray(frame["bodies"][joint["child"]]["p_NoBo_N"], float) - np.asarray(js["p_NoJ_N_parent"], float)
    v = np.cross(a, r)
    n = np.linalg.norm(v)
    return v / n if n > 1e-9 * max(1.0, np.linalg.norm(r)) else None


def direction_name(v):
    """'+z', '-x' for the N axis closest to v, with the others when they matter."""
    parts = []
    for k in np.argsort(-np.abs(v)):
        if abs(v[k]) > 0.3 or not parts:
            parts.append("%s%s" % ("+" if v[k] > 0 else "-", "xyz"[k]))
    return " ".join(parts)


def scene_warnings(geom):
    """The scene's warnings crossdyn made (the document's "warnings"): [(message, colour)], red for
    a likely mistake, orange for mirror-axes (a flipped axis sign, or the design)."""
    return [(w["message"], SYMMETRY if w.get("code") == "mirror-axes" else MISMATCH)
            for w in geom.get("warnings", [])]


def draw_configuration(painter, geom, frame, half, detail=True, labels=None, initial=False):
    """Boxes, body axes, joint points (both sides), revolute axes and the direction of a positive
    angle, spherical balls, fixed-joint squares and, at t = 0, the base's spin."""
    cols = colours(geom)
    painter.boxes([corners(b, pose, 0.015 * half) for b, pose in zip(geom["bodies"], frame["bodies"])],
                  cols, [0.22 if b.get("is_base") else 0.38 for b in geom["bodies"]])
    for i, (b, pose) in enumerate(zip(geom["bodies"], frame["bodies"])):
        p = np.asarray(pose["p_NoBo_N"], float)
        R = np.asarray(pose["R_NB"], float)
        size = np.asarray(b["shape"]["size_m"], float)
        length = float(np.clip(0.5 * size.max(), 0.12 * half, 0.26 * half)) * (1.0 if detail else 0.8)
        for k in range(3):
            painter.arrow(p, R[:, k] * length, AXIS_COLOURS[k], lw=1.7 if detail else 1.1, head=0.25)
            if detail:
                painter.text(p + R[:, k] * length * 1.14, "xyz"[k], color=AXIS_COLOURS[k], fontsize=8,
                             weight="bold", ha="center", va="center")
        painter.marker(p, s=10 if detail else 5, color="black")
        if labels is not None:
            labels.add(p, b["name"] + ((" (base, free joint)" if base_joint_free(geom) else " (base, prescribed)")
                                       if b.get("is_base") else ""),
                       colour=darker(cols[i], 0.5), size=9.5 if detail else 7.5, weight="bold", priority=3)
        nodes = pose.get("nodes_N") or [p + R @ np.asarray(n["p_BoN_B"], float) for n in b.get("nodes", [])]
        for q in nodes:
            painter.marker(np.asarray(q, float), s=14 if detail else 8, marker="D", color=darker(cols[i]))

    if "R_NO" in frame:
        draw_orbit_axes(painter, geom, frame, half, detail, labels)

    for joint, js in zip(geom["joints"], frame["joints"]):
        pp = np.asarray(js["p_NoJ_N_parent"], float)
        pc = np.asarray(js["p_NoJ_N_child"], float)
        child, parent = joint["child"], joint["parent"]
        if joint["type"] == "free":
            if initial and detail and "initial_w_NB_B_rad_s" in joint:
                w = np.asarray(frame["bodies"][child]["R_NB"], float) @ np.asarray(joint["initial_w_NB_B_rad_s"], float)
                if np.linalg.norm(w) > 0:
                    u = w / np.linalg.norm(w)
                    painter.arrow(pp, u * 0.55 * half, SPIN, lw=2.0, head=0.12, symbol_at=pp + u * 0.1 * half)
                    if labels is not None:
                        labels.add(pp + u * 0.55 * half, "w_NB(0) %s rad/s" % gfmt(np.linalg.norm(w), 3),
                                   colour=SPIN, size=8, priority=1)
            continue
        pcol = cols[parent] if parent >= 0 else "black"
        # From each body's CM to its joint point: which body a point belongs to.
        for body, point in ((parent, pp), (child, pc)):
            if body >= 0:
                painter.line([frame["bodies"][body]["p_NoBo_N"], point], color="0.25",
                             linestyle=(0, (1.5, 2)), linewidth=1.0)
        symbol = False
        if joint["type"] == "revolute":
            a = np.asarray(js["axis_N_parent"], float)
            L = 0.42 * half if detail else 0.34 * half
            symbol = painter.arrow(pp - 0.35 * a * L, a * L, AXIS_ARROW, lw=2.6 if detail else 1.7,
                                   head=0.28, symbol_at=pp)
            if js.get("axis_mismatch_rad", 0) > 1e-6:
                painter.arrow(pc, np.asarray(js["axis_N_child"], float) * L, MISMATCH, lw=2.0)
            swing(painter, frame, joint, js, half, detail, labels)
        elif joint["type"] == "prismatic" and "slide_N" in js:
            # The sliding axis through the joint point, pointing the way a positive position moves
            # the child (the point slides with it: p_PoJ_P + s axis_P).
            a = np.asarray(js["slide_N"], float)
            L = 0.42 * half if detail else 0.34 * half
            painter.arrow(pp - 0.5 * a * L, 1.5 * a * L, SLIDE_ARROW, lw=2.6 if detail else 1.7, head=0.22)
            if labels is not None:
                labels.add(pp + a * L, "+%s" % joint["name"], colour=SLIDE_ARROW, size=8, priority=1)
        elif joint["type"] == "universal" and "gimbal_axes_N" in js:
            # The two gimbal axes: the first fixed in the parent (thick), the second turning with the
            # first angle (thin).
            L = 0.42 * half if detail else 0.34 * half
            for k, width in ((0, 2.6), (1, 1.6)):
                a = np.asarray(js["gimbal_axes_N"][k], float)
                painter.arrow(pp - 0.35 * a * L, a * L, AXIS_ARROW, lw=width if detail else width * 0.65,
                              head=0.25)
        # Both sides of the joint point: a ring (parent side) and a cross (child side) inside it (in a
        # projection along a revolute axis the axis symbol marks the point instead).
        if not symbol:
            painter.marker(pp, s=110 if detail else 45, facecolor="white", edgecolor=darker(pcol, 0.5),
                           linewidth=1.6, zorder=9)
            painter.marker(pc, s=55 if detail else 25, color="black", marker="x", linewidth=1.6, zorder=10)
        if js["gap_m"] > 1e-9 * max(1.0, half):
            painter.line([pp, pc], color=MISMATCH, linewidth=2.5)
            if labels is not None:
                labels.add(0.5 * (pp + pc), "%s: points %s m apart" % (joint["name"], gfmt(js["gap_m"], 3)),
                           colour=MISMATCH, size=9, weight="bold", priority=5)
        if joint["type"] == "spherical":
            painter.ball(pp, 0.06 * half, "0.45")
        elif joint["type"] == "fixed":
            painter.marker(pp, s=120 if detail else 50, marker="s", facecolor="none", edgecolor="black",
                           linewidth=1.4)
        if labels is not None:
            label = "%s (%s%s)" % (joint["name"], joint["type"], ", offset" if joint.get("has_offset") else "")
            if joint.get("prescribed"):
                label += ", prescribed"
            labels.add(pp, label, colour=AXIS_ARROW if joint["type"] == "revolute" else "black",
                       size=8.5 if detail else 7, priority=2)


def draw_orbit_axes(painter, geom, frame, half, detail, labels):
    """The orbit frame O (LVLH) at the base's CM: o1 along-track, o2 the negative orbit normal, o3
    nadir (towards the central body), in teal, so that an attitude given relative to O can be
    checked by eye."""
    base = next((i for i, b in enumerate(geom["bodies"]) if b.get("is_base")), 0)
    p = np.asarray(frame["bodies"][base]["p_NoBo_N"], float)
    R = np.asarray(frame["R_NO"], float)
    L = (0.75 if detail else 0.6) * half
    for k, name in enumerate(("o1 along-track", "o2 -orbit normal", "o3 nadir")):
        painter.arrow(p, R[:, k] * L, ORBIT, lw=1.6 if detail else 1.0, head=0.12)
        if detail:
            painter.text(p + R[:, k] * L * 1.08, name.split()[0], color=ORBIT, fontsize=8, weight="bold",
                         ha="center", va="center")
            if labels is not None:
                labels.add(p + R[:, k] * L, name, colour=ORBIT, size=7.5, priority=1)


def base_joint_free(geom):
    """Whether the base body's joint is the free joint (else a prescribed revolute joint to N)."""
    return all(j["type"] == "free" for j in geom["joints"] if j["parent"] < 0)


def swing(painter, frame, joint, js, half, detail, labels):
    """Where the child's CM goes for a positive angle: 0 to 35 deg about the axis through the joint
    point (right-hand rule), with an arrowhead; a circular arrow round the axis when the CM is on it."""
    a = np.asarray(js["axis_N_parent"], float)
    p_J = np.asarray(js["p_NoJ_N_parent"], float)
    cm = np.asarray(frame["bodies"][joint["child"]]["p_NoBo_N"], float)
    r0 = cm - p_J
    if positive_direction(frame, joint, js) is None or np.linalg.norm(r0 - np.dot(r0, a) * a) < 0.05 * half:
        e1 = np.cross(a, [1.0, 0, 0])
        if np.linalg.norm(e1) < 0.1:
            e1 = np.cross(a, [0, 1.0, 0])
        r0 = e1 / np.linalg.norm(e1) * 0.1 * half
        start, span = p_J + 0.1 * half * a, math.radians(270)
    else:
        start, span = p_J, math.radians(35)
    pts = np.array([start + rodrigues(a, th) @ r0 for th in np.linspace(0.0, span, 24)])
    if isinstance(painter, Painter2D):  # seen nearly edge-on in this projection: left out
        flat = np.array([painter.project(p) for p in pts])
        if np.sum(np.linalg.norm(np.diff(flat, axis=0), axis=1)) < 0.5 * np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)):
            return
    painter.line(pts, color=SWING, linestyle=(0, (3, 1.5)), linewidth=2.2 if detail else 1.3)
    tangent = pts[-1] - pts[-3]
    tangent = tangent / np.linalg.norm(tangent) * (0.10 if detail else 0.07) * half
    painter.arrow(pts[-1] - 0.5 * tangent, tangent, SWING, lw=2.2 if detail else 1.3, head=0.9)
    if labels is not None and detail:
        labels.add(pts[-1], "+%s" % joint["name"], colour=SWING, size=8, priority=1)


def draw_N_axes(painter, lo, hi, half, labels=None):
    """N's axes at its origin (at the lower corner of the view, and said so, when the origin is
    outside it)."""
    L = 0.6 * half
    origin = np.zeros(3)
    far = bool(np.any(origin < lo) or np.any(origin > hi))
    if far:
        origin = lo + 0.1 * (hi - lo)
    for k in range(3):
        e = np.zeros(3)
        e[k] = min(L, 0.8 * (hi[k] - origin[k]))
        painter.line([origin, origin + e], color=N_COLOUR, linestyle=(0, (6, 3)), linewidth=1.0)
        painter.text(origin + e * 1.06, "N" + "xyz"[k], color=N_COLOUR, fontsize=8, ha="center", va="center")
    if far and labels is not None:
        labels.add(origin, "N's axes (its origin is off the view)", colour=N_COLOUR, size=7, priority=0)


# ----------------------------------------------------------------------------------------------
# Figures


def setup_3d(ax, lo, hi, labels=True, zoom=1.0):
    ax.computed_zorder = False  # boxes (one depth-sorted collection) under lines, points, labels
    ax.set_proj_type("ortho")
    ax.view_init(**VIEW)
    for setter, a, b in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), lo, hi):
        setter(a, b)
    ax.set_box_aspect(tuple(hi - lo), zoom=zoom)  # equal scale on the three axes
    if labels:
        ax.set_xlabel("N x (m)", labelpad=0, fontsize=8)
        ax.set_ylabel("N y (m)", labelpad=0, fontsize=8)
        ax.set_zlabel("N z (m)", labelpad=0, fontsize=8)
    ax.tick_params(labelsize=6.5, pad=0)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.pane.set_alpha(0.03)


def setup_2d(ax, lo, hi, i, j, title):
    ax.set_xlim(lo[i], hi[i])
    ax.set_ylim(lo[j], hi[j])
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("N %s (m)" % "xyz"[i], fontsize=7.5, labelpad=1)
    ax.set_ylabel("N %s (m)" % "xyz"[j], fontsize=7.5, labelpad=1)
    ax.tick_params(labelsize=6.5, pad=1)
    ax.grid(True, alpha=0.25)
    ax.set_title(title, fontsize=8.5, pad=3)


def legend_handles(geom):
    types = {j["type"] for j in geom["joints"]}
    axes = tuple(Line2D([], [], color=c, lw=2.2) for c in AXIS_COLOURS)
    h = [(axes, "body frame axes x, y, z"),
         (Patch(facecolor="0.8", edgecolor="0.4"), "body: its equivalent-inertia box")]
    if types - {"free"}:
        h += [(Line2D([], [], marker="o", color="none", markerfacecolor="white", markeredgecolor="0.3",
                      markeredgewidth=1.6, markersize=9), "joint point from the parent (ring)"),
              (Line2D([], [], marker="x", color="black", lw=0, markersize=7, markeredgewidth=1.6),
               "joint point from the child (cross, in the ring)"),
              (Line2D([], [], color="0.25", linestyle=(0, (1.5, 2))), "a body's CM to its joint points"),
              (Line2D([], [], color=MISMATCH, lw=2.5), "red: something that must agree does not")]
    if "revolute" in types:
        h += [(Line2D([], [], color=AXIS_ARROW, lw=2.6), "revolute axis; in 2-D along the view: \u2299 towards you, \u2297 away"),
              (Line2D([], [], color=SWING, lw=1.8, linestyle=(0, (4, 2))), "child CM's path as the angle grows")]
    if "prismatic" in types:
        h.append((Line2D([], [], color=SLIDE_ARROW, lw=2.6), "prismatic axis: the way a positive position slides the child"))
    if "universal" in types:
        h.append((Line2D([], [], color=AXIS_ARROW, lw=2.6), "universal joint: first axis (thick), second (thin)"))
    if "spherical" in types:
        h.append((Line2D([], [], marker="o", color="none", markerfacecolor="0.6", markersize=11, alpha=0.5),
                  "spherical joint"))
    if "fixed" in types:
        h.append((Line2D([], [], marker="s", color="none", markeredgecolor="black", markersize=8),
                  "fixed joint"))
    h.append((Line2D([], [], color=SPIN, lw=2.0), "base's initial angular velocity"))
    h.append((Line2D([], [], color=N_COLOUR, linestyle=(0, (6, 3))), "frame N's axes, at its origin"))
    if "orbit" in geom:
        h.append((Line2D([], [], color=ORBIT, lw=1.6), "orbit frame O (LVLH) at the base: o1 along-track, o3 nadir"))
    return h


def conventions_text():
    return ("Drawn from the scene as crossdyn read it (SI units; N is the inertial frame). Each body is "
            "the uniform box with its mass and principal moments of inertia, along its principal axes, "
            "centred at its CM. A joint point is drawn from both bodies: parent p_Po + R_NP parent_point, "
            "child p_Co + R_NC child_point. A revolute joint turns the child about its axis (given in "
            "the parent frame) by the right-hand rule, R_PC = R_offset Rot(axis, angle); the dashed "
            "arc shows where the child's CM goes as the angle grows. Spherical: R_PC = R_offset R(q_J). "
            "Prismatic: the child slides along the axis, R_PC = R_offset. Universal: R_PC = "
            "Rot(axis, angle1) Rot(axis2, angle2) R_offset.")


def joint_notes(geom, frame):
    notes = []
    for joint, js in zip(geom["joints"], frame["joints"]):
        if joint["type"] != "revolute":
            continue
        d = positive_direction(frame, joint, js)
        child = geom["bodies"][joint["child"]]["name"]
        if joint["parent"] < 0:  # a prescribed base: its axis is given in N
            notes.append("%s: axis %s in N, fixed; the angle is prescribed%s" % (
                joint["name"], _v(js["axis_N_parent"]), " (offset)" if joint.get("has_offset") else ""))
            continue
        parent = geom["bodies"][joint["parent"]]["name"]
        notes.append("%s: axis %s in %s, %s in N%s; + angle moves %s %s" % (
            joint["name"], _v(joint["axis_P"]), parent, _v(js["axis_N_parent"]),
            " (offset)" if joint.get("has_offset") else "", child,
            ("towards N " + direction_name(d)) if d is not None else "about its own CM"))
    return notes


def _v(v):
    return "(" + ", ".join(gfmt(round(x, 12) + 0.0, 3) for x in v) + ")"


def draw_initial(fig, geom, title=None):
    """The scene at t = 0: a 3-D view, three projections, a legend, notes and conventions."""
    frame = geom["initial"]
    lo, hi, half = scene_limits(geom, [frame])
    ax = fig.add_axes([0.0, 0.25, 0.56, 0.68], projection="3d")
    setup_3d(ax, lo, hi, zoom=1.1)
    p3 = Painter3D(ax)
    labels = Labels()
    draw_N_axes(p3, lo, hi, half, labels)
    draw_configuration(p3, geom, frame, half, detail=True, labels=labels, initial=True)
    for k, (name, i, j) in enumerate(PROJECTIONS):
        a2 = fig.add_axes([0.635, 0.715 - 0.24 * k, 0.35, 0.185])
        setup_2d(a2, lo, hi, i, j, name)
        p2 = Painter2D(a2, i, j)
        draw_N_axes(p2, lo, hi, half)
        lab2 = Labels()
        draw_configuration(p2, geom, frame, half, detail=False, labels=lab2, initial=True)
        lab2.place(p2, fig, min_priority=3)
    handles = legend_handles(geom)
    fig.legend([h for h, _ in handles], [t for _, t in handles], loc="lower left", ncol=3,
               bbox_to_anchor=(0.01, 0.085), fontsize=7.8, frameon=False,
               handler_map={tuple: HandlerTuple(ndivide=None, pad=0.3)})
    for text, colour, weight, size, y in text_lines(scene_warnings(geom), joint_notes(geom, frame)):
        fig.text(0.015, y, text, fontsize=size, color=colour, weight=weight, ha="left", va="top")
    fig.suptitle(title or "%s at t = 0, as crossdyn read it" % geom.get("scene", ""), fontsize=12, y=0.985)
    fig.text(0.015, 0.008, conventions_text(), fontsize=7.3, wrap=True, va="bottom", ha="left", color="0.25")
    labels.place(p3, fig)
    return ax


def text_lines(warnings, notes, top=0.245):
    """The lines under the 3-D view, above the legend: every scene warning first (bold, in its
    colour), then the joints' notes while there is room: 5 lines at 8 pt, or up to 8 at 7 pt.
    Past 8 warnings the last line says how many more there are. [(text, colour, weight, size, y)]."""
    lines = [(w, colour, "bold") for w, colour in warnings]
    if len(lines) > 8:
        lines = lines[:7] + [("... and %d more scene warnings (printed by crossdyn, and in the report)"
                              % (len(lines) - 7), MISMATCH, "bold")]
    lines += [(n, "0.1", "normal") for n in notes][:max(0, (5 if len(lines) <= 5 else 8) - len(lines))]
    size, step = (8, 0.018) if len(lines) <= 5 else (7, 0.0115)
    return [(text, colour, weight, size, top - k * step) for k, (text, colour, weight) in enumerate(lines)]


def motion_title(geom):
    m = geom.get("motion", {})
    frames = m.get("frames", [])
    engine = m.get("engine") or "kane"
    if m.get("state") == "not run":
        return "No later configurations: %s" % (m.get("note") or "no run")
    text = "Later configurations from the %s run at the scene's settings (system CM at N's origin)" % engine
    if m.get("state") == "failed":
        text += "\nthe run failed, so only %d time%s can be shown: %s" % (
            len(frames), "" if len(frames) == 1 else "s", m.get("note", ""))
    return text


def draw_motion(fig, geom, panels=4):
    """A row of small 3-D views of the later configurations, the same view and scale in each."""
    m = geom.get("motion", {})
    frames = m.get("frames", [])
    fig.suptitle(motion_title(geom), fontsize=10.5, y=0.985)
    if not frames:
        return []
    lo, hi, half = scene_limits(geom, frames)
    width = 0.86 / max(len(frames), panels)
    axes = []
    for k, f in enumerate(frames):
        ax = fig.add_axes([k * width, 0.0, width, 0.86], projection="3d")
        setup_3d(ax, lo, hi, labels=False)
        # Small panels: the grid without numbers (the view at t = 0 above has the scale).
        ax.set_xticklabels([])
        ax.set_yticklabels([])
        ax.set_zticklabels([])
        painter = Painter3D(ax)
        draw_N_axes(painter, lo, hi, half)
        draw_configuration(painter, geom, f, half, detail=False)
        # The run's attitudes must keep each revolute axis fixed in both bodies (the points agree by
        # construction here): say so in red when they do not.
        bad = [j["name"] for j, js in zip(geom["joints"], f["joints"]) if js.get("axis_mismatch_rad", 0) > 1e-6]
        ax.set_title("t = %s s" % gfmt(f["t"], 4) + ("\naxis off: " + ", ".join(bad) if bad else ""),
                     fontsize=9.5, pad=0, color=MISMATCH if bad else "black")
        axes.append(ax)
    if len(frames) < panels and m.get("state") == "failed":
        ax = fig.add_axes([len(frames) * width, 0.0, width, 0.86])
        ax.axis("off")
        ax.text(0.5, 0.5, "the run failed:\nno later picture", ha="center", va="center", color=MISMATCH,
                fontsize=10)
    cols = colours(geom)
    fig.legend([Patch(facecolor=c, edgecolor=darker(c), alpha=0.6) for c in cols],
               [b["name"] for b in geom["bodies"]], loc="center left", bbox_to_anchor=(0.865, 0.45),
               fontsize=8, frameon=False, title="bodies", title_fontsize=8.5)
    return axes


def initial_png(geom):
    fig = plt.figure(figsize=(12, 9.2))
    draw_initial(fig, geom)
    return png_bytes(fig)


def motion_png(geom, panels=4):
    fig = plt.figure(figsize=(12, 3.5))
    draw_motion(fig, geom, panels)
    return png_bytes(fig)


def combined_png(geom, panels=4):
    """`crossdyn draw`: the t = 0 views over the row of later configurations, in one PNG."""
    fig = plt.figure(figsize=(12, 12.9))
    top, bottom = fig.subfigures(2, 1, height_ratios=[9.2, 3.7])
    draw_initial(top, geom)
    draw_motion(bottom, geom, panels)
    return png_bytes(fig)
