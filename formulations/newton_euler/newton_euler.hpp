// The Newton-Euler engine: maximal coordinates, one set of Newton-Euler equations per body, the
// joint constraint forces and moments as unknowns (reference paper, "Newton-Euler Equations",
// Eqs. (1), (2), (7); the paper's model-specific code for Example 1).
//
// State x (13 per body; n = number of bodies):
//   x[7b .. 7b+7)          body b: p_NoBo_N (3), q_NB (4, scalar first; kept near unit norm)
//   x[7n+6b .. 7n+6b+6)    body b: v_NBo_N (3), w_NB_B (3)
// Labels "<body>.x/.y/.z/.qw/.qx/.qy/.qz/.vx/.vy/.vz/.wx/.wy/.wz".
//
// Equations (per right-hand-side call, named passes in newton_euler.cpp):
//   body_pass      x => R_NB, p, v, w of every body
//   joint_pass     => relative joint kinematics, constraint rows g, J, gamma (joint_constraints.hpp)
//   force_pass     t => f_b = [F_ext (zero: no external forces in the model);
//                              M_ext + spring/damper/motor torques - w x I w]   (Eqs. (1), (7))
//   solve_pass     [M J^T; J 0] [nu'; -lambda] = [f; gamma_s], factorised in O(n) (tree_kkt.hpp):
//                  M nu' = f + J^T lambda, J nu' = gamma_s, the constraint wrench on body b is
//                  J_b^T lambda. gamma_s = gamma (stabilisation none or projection), or
//                  gamma - alpha g' - beta g (Baumgarte 1972: g'' + alpha g' + beta g = 0).
//   xdot           p' = v, q' = 1/2 q (x) (0, w), v' = a, w' = alpha.
// Stabilisation (EngineOptions::stabilization): "projection" (default) projects positions (Newton
// iterations) and then velocities onto the constraint manifold, in the mass metric, after every
// accepted step whose violation exceeds 1e-12 per metre of the model's size (Hairer, Lubich &
// Wanner 2006, "Geometric Numerical Integration", Sec. IV.4; Hairer & Wanner 1996, Sec. VII.2);
// "baumgarte"; "none" (drift shows).
//
// Extra output columns after the pinned ones:
//   per joint other than the free one: <joint>.fx .fy .fz (N) .mx .my .mz (N m): the constraint
//     force and the constraint moment about the joint point exerted BY THE PARENT ON THE CHILD,
//     in the parent frame (springs, dampers and motors are not included: they are applied loads);
//   constraint.pos (m) and constraint.vel (m/s): largest distance between the two copies of a
//     joint point, and the largest relative velocity of those copies, over the joints;
//   constraint.ang (rad), constraint.angvel (rad/s): largest attitude violation (revolute: angle
//     between the two copies of the axis; fixed: rotation angle away from the offset) and the norm
//     of the forbidden relative angular velocity.
#pragma once

#include "core/engine.hpp"

#include <memory>

namespace crossdyn {

// Throws InputError for flexible bodies, a free joint other than joints[0], an unknown
// stabilisation name, negative Baumgarte gains or a non-positive test_inertia_scale.
std::unique_ptr<Engine> make_newton_euler_engine(const System& system, const EngineOptions& options);

}  // namespace crossdyn
