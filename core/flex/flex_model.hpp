// Modal data for flexible bodies: what both sources (the beam generator, core/flex/beam.hpp, and
// nodal data files, core/flex/nodal_csv.hpp) produce, and the checks they share.
//
// The model is pinned in docs/flexible-bodies.md and core/system.hpp (FlexBody, FlexNode):
// nodes with mass m_i at p_i (from the undeformed CM Bo, body frame), rigid inertia J_i, mode
// shapes Phi_i and slopes Psi_i (3 x n each), modal stiffness K and damping D (n x n). The scene
// keys that describe one are in docs/flexible-data.md.
//
// This is shared code in core/: the scene reader calls it and stores the FlexBody in the System;
// the engines consume the FlexBody but never call anything here.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include "core/system.hpp"

namespace crossdyn::flex {

// A flexible body's modal data with the rigid properties the scene reader puts in Body.
struct FlexModel {
  FlexBody flex;                                           // positions from the undeformed CM Bo
  double mass = 0;                                         // sum m_i, kg (Body::mass)
  Eigen::Matrix3d I_BBo_B = Eigen::Matrix3d::Zero();       // sum (J_i + m_i (|p_i|^2 1 - p_i p_i^T))
  // Where Bo lies in the frame the source gave positions in (R: a nodal file's own origin, same
  // axes as B): points of this body given in R become points from Bo by subtracting it, as for a
  // rigid body's `center_of_mass`. Zero for the beam generator (its nodes are built about Bo).
  Eigen::Vector3d p_RoBo_R = Eigen::Vector3d::Zero();
};

// The rigid mass and inertia about the origin of the nodes (docs/flexible-bodies.md "Nodes,
// modes, deformation"): m = sum m_i, I = sum_i (J_i + m_i (|p_i|^2 1 - p_i p_i^T)).
struct RigidProperties {
  double mass = 0;
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
};
RigidProperties rigid_properties(const FlexBody& f);

// The mass matrix of the free body at rest and undeformed: the Hessian of the kinetic energy
// T = 1/2 sum_i m_i |v + w x p_i + Phi_i eta'|^2 + 1/2 sum_i w . J_i w with respect to the speeds
// (v, w, eta') (all in body components), (6 + n) x (6 + n). The node velocity is B_i (v, w, eta')
// with B_i = [1, -[p_i x], Phi_i], so M = sum_i m_i B_i^T B_i + blockdiag(0, sum J_i, 0). Its
// modal block is the discrete modal mass sum_i m_i Phi_i^T Phi_i; its coupling blocks
// sum m_i Phi_i and sum m_i [p_i x] Phi_i vanish for free-free modes of a continuum (for the
// beam generator to rounding: its mass points integrate exactly). Used by validate_flex (a mode
// that is a rigid motion makes it singular) and by tests (the small-motion frequencies of a free body: K x = omega^2 M x with K padded by zeros).
Eigen::MatrixXd rest_mass_matrix(const FlexBody& f);

// Limits against hostile or mistaken input, shared by both sources (docs/flexible-data.md).
inline constexpr std::size_t kMaxNodes = 200000;
inline constexpr int kMaxModes = 1000;
inline constexpr std::size_t kMaxNameLength = 64;

// A node or mode name: 1 to 64 letters, digits, '_' or '-', starting with a letter (the scene's
// Name rule; no '.', which separates a mode from its component in nodal files). Returns what is
// wrong, or nothing.
std::optional<std::string> name_problem(std::string_view name);

// A mode name must also not clash with a body's own output columns (<body>.wx ... <body>.qz) or
// with another mode's rate column (<body>.<mode>_rate). Returns what is wrong, or nothing.
std::optional<std::string> mode_name_problem(std::string_view name);

// A rigid rotational inertia (a node's J_i): finite, symmetric, positive semi-definite and
// physically realisable (principal moments satisfy I1 + I2 >= I3 for each permutation), with a
// tolerance of 1e-9 relative to its largest entry. Returns what is wrong, or nothing.
std::optional<std::string> inertia_problem(const Eigen::Matrix3d& J);

// A modal stiffness or damping matrix: n x n, finite, symmetric to 1e-9 relative to its largest
// entry, positive semi-definite (smallest eigenvalue >= -1e-9 times the largest |eigenvalue|).
// `what` names it in the message ("K"). Returns what is wrong (naming the modes), or nothing.
std::optional<std::string> modal_matrix_problem(const Eigen::MatrixXd& A, const FlexBody& f,
                                                std::string_view what);

// Every check of a FlexBody, whatever built it (docs/flexible-data.md "What is checked"):
// mode names (valid, unique, no clash with output columns); sizes (Phi_i, Psi_i 3 x n; K, D n x n);
// at least one node, at most kMaxNodes, at most kMaxModes; node names valid and unique; masses
// finite and >= 0 with a positive total; every number finite; each J_i a realisable inertia;
// the nodes' CM at the body origin (|sum m_i p_i| <= 1e-9 m max|p_i|); the rigid inertia positive
// definite; every mode moving some mass and no mode a rigid motion or a combination of the others
// (the rest mass matrix, scaled to unit diagonal, has its smallest eigenvalue above 1e-10);
// K and D symmetric positive semi-definite; geometric stiffening only with at least one mode, and
// then every G_i n x n, finite and symmetric and every e_i a unit vector. Throws InputError
// "<context>: <what is wrong>", naming the node or mode.
void validate_flex(const FlexBody& f, const std::string& context);

}  // namespace crossdyn::flex
