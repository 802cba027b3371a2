#!/usr/bin/python3
"""Writes the chainN scene (docs/scenarios.md, Scene 3: chain5 with N links) to stdout.

    scripts/make_chain.py N [--duration T] [--output-step H] > chainN.yaml

Used to measure how crossdyn scales and how fast it stops (docs/stopping.md).
"""
import argparse

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("n", type=int, help="number of links (>= 1)")
p.add_argument("--duration", type=float, default=10.0, help="run length, s (default 10)")
p.add_argument("--output-step", type=float, default=0.1, help="output step, s (default 0.1)")
a = p.parse_args()
if a.n < 1:
    p.error("N must be at least 1")

# YAML anchors keep the file small (chain5000 is under the reader's 1 MiB limit).
out = [f"# chain{a.n}: scripts/make_chain.py {a.n}; chain5 of docs/scenarios.md Scene 3 with {a.n} links.",
       f"name: chain{a.n}",
       f"description: {a.n} identical slender links joined end to end by spherical joints (chainN).",
       "source: crossdyn's own scaling scene, docs/scenarios.md Scene 3 (chainN).",
       "bodies:",
       "  - {name: link1, mass: 10, inertia: &I [0.1, 3.4, 3.4]}"]
for k in range(2, a.n + 1):
    out.append(f"  - {{name: link{k}, mass: 10, inertia: *I}}")
out.append("joints:")
out.append("  - {name: joint1, type: free, child: link1, initial: {angular_velocity: [0.3, 0.2, 0.5]}}")
for k in range(2, a.n + 1):
    anchors = "parent_point: &P [1, 0, 0], child_point: &C [-1, 0, 0], " \
              "initial: &W {angular_velocity: [0.1, -0.2, 0.3]}" if k == 2 else \
              "parent_point: *P, child_point: *C, initial: *W"
    out.append(f"  - {{name: joint{k}, type: spherical, parent: link{k-1}, child: link{k}, {anchors}}}")
out.append(f"run: {{duration: {a.duration!r}, output_step: {a.output_step!r}, integrator: rkf78, "
           "rtol: 1e-10, atol: 1e-10}")
print("\n".join(out))
