#!/usr/bin/python3
"""Draws the figures of docs/scene-format.md (Debian's matplotlib: run with /usr/bin/python3).

    /usr/bin/python3 docs/figures/make_figures.py      # writes docs/figures/joint_frames.png

joint_frames.png: a revolute joint seen along its axis (z out of the page), in three steps:
(a) the joint point J from each body's centre of mass, (b) the offset, the child frame's attitude
in the parent frame at angle zero, (c) the joint angle, turning the child about the axis given in
the parent frame: R_PC = Rot(axis_P, angle) R_offset.
"""
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Arc, FancyArrowPatch, Polygon  # noqa: E402

PARENT = "#4c72b0"
CHILD = "#dd8452"
POINT = "#222222"


def rot(a, v):
    c, s = math.cos(a), math.sin(a)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1])


def add(a, b):
    return (a[0] + b[0], a[1] + b[1])


def scale(k, v):
    return (k * v[0], k * v[1])


def box(ax, centre, half, angle, color, dashed=False):
    corners = [(-half[0], -half[1]), (half[0], -half[1]), (half[0], half[1]), (-half[0], half[1])]
    pts = [add(centre, rot(angle, c)) for c in corners]
    ax.add_patch(Polygon(pts, closed=True, facecolor=color, alpha=0.10 if dashed else 0.22,
                         edgecolor=color, linestyle="--" if dashed else "-", linewidth=1.2))


def arrow(ax, a, b, color, width=1.6, style="-|>", dashed=False):
    ax.add_patch(FancyArrowPatch(a, b, arrowstyle=style, mutation_scale=13, color=color,
                                 linewidth=width, linestyle="--" if dashed else "-",
                                 shrinkA=0, shrinkB=0))


def frame(ax, origin, angle, color, name, length=0.7, dashed=False):
    for k, axis in enumerate(("x", "y")):
        tip = add(origin, rot(angle + k * math.pi / 2, (length, 0)))
        arrow(ax, origin, tip, color, width=1.3, dashed=dashed)
        label = add(origin, rot(angle + k * math.pi / 2, (length + 0.17, 0)))
        ax.text(label[0], label[1], f"${axis}_{name}$", color=color, ha="center", va="center",
                fontsize=11)


def dot(ax, p, label, offset=(0.08, -0.2), color=POINT):
    ax.plot([p[0]], [p[1]], "o", color=color, markersize=5, zorder=5)
    ax.text(p[0] + offset[0], p[1] + offset[1], label, color=color, fontsize=11)


def panel(ax, title):
    ax.set_aspect("equal")
    ax.set_xlim(-1.5, 3.7)
    ax.set_ylim(-1.75, 2.3)
    ax.axis("off")
    ax.set_title(title, fontsize=11.5, loc="left")


def parent(ax, J):
    Po = (0.0, -0.5)
    box(ax, Po, (1.3, 0.5), 0.0, PARENT)
    frame(ax, Po, 0.0, PARENT, "P", length=0.55)
    dot(ax, Po, "$P_o$ (CM)", offset=(-0.6, -0.3), color=PARENT)
    arrow(ax, Po, J, POINT, width=1.3)
    ax.text(0.25, -0.05, "parent_point", fontsize=9.5, color=POINT, rotation=21)
    dot(ax, J, "$J$", offset=(0.12, -0.3))
    # The axis (z_P) points out of the page at J.
    ax.plot([J[0]], [J[1]], "o", markersize=13, markerfacecolor="none", markeredgecolor="k")


def child(ax, J, angle, child_point, dashed=False, labels=True, side_sign=-1):
    Co = add(J, rot(angle, scale(-1, child_point)))  # J = Co + R_PC child_point
    box(ax, add(J, rot(angle, (0.9, 0))), (1.05, 0.28), angle, CHILD, dashed)
    if not dashed:
        frame(ax, Co, angle, CHILD, "C", length=0.55)
    if labels:
        dot(ax, Co, "$C_o$ (CM)", offset=(0.05, 0.12), color=CHILD)
        arrow(ax, Co, J, CHILD, width=1.3)
        mid = add(Co, scale(0.5, rot(angle, child_point)))
        side = add(mid, rot(angle, (0.0, side_sign * 0.42)))
        ax.text(side[0], side[1], "child_point", fontsize=9.5, color=CHILD, ha="center",
                va="center", rotation=(math.degrees(angle) + 90) % 180 - 90)
    return Co


def main():
    J = (1.3, 0.0)
    child_point = (-0.9, 0.0)  # in the child frame: from the child's CM back to the joint
    fig, axes = plt.subplots(1, 3, figsize=(15.5, 4.7))

    ax = axes[0]
    panel(ax, "(a) points: parent_point in P, child_point in C\n"
              "(offset identity, angle 0: C parallel to P)")
    parent(ax, J)
    child(ax, J, 0.0, child_point)
    ax.text(-1.4, -1.65, "child_point = [-0.9, 0, 0]: from the child's CM\nback to J (towards the "
            "parent)", fontsize=9.5, color=CHILD)

    ax = axes[1]
    offset = math.radians(90)
    panel(ax, "(b) offset: C's attitude in P at angle 0\n"
              "offset = {axis: [0, 0, 1], angle: 90 deg}")
    parent(ax, J)
    arrow(ax, J, add(J, (0.5, 0)), PARENT, width=1.1, dashed=True)
    child(ax, J, offset, child_point, side_sign=1)
    ax.add_patch(Arc(J, 0.75, 0.75, theta1=0, theta2=90, color="k", linewidth=1.1))
    arrow(ax, add(J, rot(math.radians(80), (0.375, 0))), add(J, rot(math.radians(92), (0.375, 0))),
          "k", width=1.1)
    ax.text(J[0] + 0.36, J[1] + 0.36, "90°", fontsize=10)
    ax.text(-1.4, -1.65, "columns of R_offset = C's axes in P:\n$x_C = y_P$, $y_C = -x_P$",
            fontsize=9.5)

    ax = axes[2]
    angle = math.radians(35)
    panel(ax, "(c) angle about axis = [0, 0, 1] (parent frame, out of the page)\n"
              "R_PC = Rot(axis_P, angle) R_offset")
    parent(ax, J)
    child(ax, J, offset, child_point, dashed=True, labels=False)
    child(ax, J, offset + angle, child_point)
    ax.add_patch(Arc(J, 1.3, 1.3, theta1=90, theta2=90 + 35, color="k", linewidth=1.1))
    arrow(ax, add(J, rot(math.radians(118), (0.65, 0))), add(J, rot(math.radians(127), (0.65, 0))),
          "k", width=1.1)
    ax.text(J[0] + 0.32, J[1] + 0.7, "angle > 0", fontsize=10)
    ax.text(-1.4, -1.65, "the child turns about the parent-frame axis through J,\nright-hand rule; "
            "dashed: angle 0", fontsize=9.5)

    fig.tight_layout()
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "joint_frames.png")
    fig.savefig(out, dpi=100)
    print("wrote", out)


if __name__ == "__main__":
    main()
