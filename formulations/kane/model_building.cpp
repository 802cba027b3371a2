// Construction of the Kane engine: validate the tree, build the node tables (the model, fixed for
// the engine's life), size the workspace that rhs() reuses, and choose the solver (README.md
// "Two solvers").
#include "formulations/kane/kane_internal.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/scene/topology.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Construction: validate the tree, build the node tables, size the workspace.

namespace {
// The engine's copy of the scene with every joint damper (both universal axes) times
// EngineOptions::test_damper_scale (core/engine.hpp, issue 26): the equations of motion read
// System::joints. Scale 1 (every real run): an exact copy, so nothing changes.
System damper_scaled(const System& system, double scale) {
  System s = system;
  if (scale != 1.0)
    for (Joint& J : s.joints) {
      J.damping *= scale;
      J.damping2 *= scale;
    }
  return s;
}
}  // namespace

KaneModel::KaneModel(const System& system, double damper_scale)
    : system_(damper_scaled(system, damper_scale)), layout_(system_) {}

KaneEngine::KaneEngine(const System& system, const EngineOptions& options, KaneSolver solver)
    : KaneModel(system, options.test_damper_scale) {
  const std::string file = where(system_);
  const std::size_t nj = system_.joints.size(), nb = system_.bodies.size();
  // The tree (one free joint first, every parent the child of an earlier joint, one joint per
  // body, indices in range): the one public check, core/scene/topology.hpp.
  check_topology(system_);
  if (!(options.test_inertia_scale > 0) || !std::isfinite(options.test_inertia_scale))
    throw InputError("engine option test_inertia_scale must be positive and finite");
  if (!(options.test_damper_scale >= 0) || !std::isfinite(options.test_damper_scale))
    throw InputError("engine option test_damper_scale must be finite and not negative");
  if (options.test_gyroscopic_sign != 1.0 && options.test_gyroscopic_sign != -1.0)
    throw InputError("engine option test_gyroscopic_sign must be 1 or -1");
  gyro_sign_ = options.test_gyroscopic_sign;

  // Flexible bodies: validated, modal integrals built once.
  std::vector<int> flex_of_body(nb, -1);
  for (std::size_t b = 0; b < nb; ++b) {
    const Body& B = system_.bodies[b];
    if (!B.flex) continue;
    flex_of_body[b] = static_cast<int>(flex_.size());
    flex_.push_back(build_flex_model(B, file, options.test_inertia_scale));
    // The modal damper in the equations of motion times test_damper_scale; P keeps the scene's.
    FlexModel& F = flex_.back();
    F.D_P = F.D;
    if (options.test_damper_scale != 1.0) F.D *= options.test_damper_scale;
  }

  // The exact tangent (tangent.cpp; issue 27) covers rigid trees and flexible bodies (with or
  // without geometric stiffening) at test_inertia_scale 1 (its flexible twin sums the node masses
  // and inertias, which a scaled inertia no longer is) and test_gyroscopic_sign 1.
  tangent_ = flex_.empty() ||
             (options.test_inertia_scale == 1.0 && options.test_gyroscopic_sign == 1.0);
  // Its output row (output_row_tangent) covers the same Systems.
  output_tangent_ = tangent_;

  nodes_.resize(nj);
  std::vector<int> node_of_body(nb, -1);
  int nq = 0, nu = 0;
  for (std::size_t k = 0; k < nj; ++k) {
    cancel::poll();
    const Joint& J = system_.joints[k];
    Node& n = nodes_[k];
    const std::string jname = file + ": joint '" + J.name + "'";
    n.joint = static_cast<int>(k);
    n.body = J.child;
    if (k > 0) n.parent = node_of_body[static_cast<std::size_t>(J.parent)];
    node_of_body[static_cast<std::size_t>(J.child)] = static_cast<int>(k);
    const Body& B = system_.bodies[static_cast<std::size_t>(J.child)];
    if (!(B.mass > 0) || !std::isfinite(B.mass))
      throw InputError(file + ": body '" + B.name + "': mass must be positive");
    n.flex = flex_of_body[static_cast<std::size_t>(J.child)];
    n.mass = n.flex >= 0 ? flex_[static_cast<std::size_t>(n.flex)].mass : B.mass;
    n.I_BBo_B = options.test_inertia_scale * 0.5 * (B.I_BBo_B + B.I_BBo_B.transpose());
    n.q_PJ0 = J.q_PJ0.normalized();
    n.R_PJ0 = n.q_PJ0.toRotationMatrix();
    n.has_offset = !n.R_PJ0.isIdentity(0.0);
    n.p_PoJ_P = J.p_PoJ_P;
    n.p_CoJ_C = J.p_CoJ_C;
    n.body_torque = !B.torque.empty();
    n.damping_P = system.joints[k].damping;  // the scene's, unscaled (P)
    n.damping2_P = system.joints[k].damping2;
    n.hinge_load = J.stiffness != 0 || J.damping != 0 || !J.motor_revolute.empty() ||
                   !J.motor_spherical.empty() || J.stiffness2 != 0 || J.damping2 != 0 ||
                   !J.motor_universal.empty();
    if (n.flex < 0) {
      const Matrix3d& I = n.I_BBo_B;
      if (I(1, 0) == 0 && I(2, 0) == 0 && I(2, 1) == 0)
        n.inertia = I(0, 0) == I(1, 1) && I(1, 1) == I(2, 2) ? Node::Inertia::Isotropic
                                                              : Node::Inertia::Diagonal;
    }
    // The joint type's own facts (the shape of its speeds, axes, prescribed motion, Node::slides
    // and axis_rates), set and validated by its unit (joints/): the passes read these, never the
    // type.
    n.unit = &joint_unit(J.type);
    n.shape = n.unit->shape;
    if (n.unit->build) n.unit->build(J, n, jname);
    if (n.prescribed) has_prescribed_ = true;

    // Attachment at nodes of flexible bodies (docs/flexible-bodies.md "Joints at nodes").
    auto attach = [&](int body, int node, const Eigen::Vector3d& point, const char* side,
                      Eigen::Matrix3Xd& Phi, Eigen::Matrix3Xd& Psi, bool& stiff,
                      Eigen::Vector3d& e, Eigen::MatrixXd& G) -> bool {
      const Body& A = system_.bodies[static_cast<std::size_t>(body)];
      if (node < 0) {
        if (A.flex) {  // attached to the body frame itself: no shape, no slope
          Phi = Eigen::Matrix3Xd::Zero(3, A.flex->modes());
          Psi = Phi;
        }
        return false;
      }
      if (!A.flex)
        throw InputError(jname + ": " + side + "_node is set but body '" + A.name + "' is rigid");
      if (node >= static_cast<int>(A.flex->nodes.size()))
        throw InputError(jname + ": " + side + "_node " + std::to_string(node) + " of body '" +
                         A.name + "' does not exist (it has " +
                         std::to_string(A.flex->nodes.size()) + " nodes)");
      const FlexNode& fn = A.flex->nodes[static_cast<std::size_t>(node)];
      if ((point - fn.p_BoNi_B).norm() > 1e-9 * (1.0 + fn.p_BoNi_B.norm()))
        throw InputError(jname + ": " + side + "_point differs from the position of node '" +
                         fn.name + "' of body '" + A.name + "'");
      const Eigen::Index m = A.flex->modes();
      Phi = fn.Phi_B.cols() ? fn.Phi_B : Eigen::Matrix3Xd::Zero(3, m);
      Psi = fn.Psi_B.cols() ? fn.Psi_B : Eigen::Matrix3Xd::Zero(3, m);
      // Geometric stiffening: the node also moves by e (1/2 eta^T G eta) (docs "Joints at nodes").
      stiff = A.flex->geometric_stiffening && fn.G.size() > 0 && fn.G.cwiseAbs().maxCoeff() > 0 &&
              fn.e_B.squaredNorm() > 0;
      if (stiff) {
        e = fn.e_B;
        G = 0.5 * (fn.G + fn.G.transpose());
      }
      // a node that never moves: rigid attachment
      return stiff || !(all_zero(Phi) && all_zero(Psi));
    };
    if (k > 0) {
      n.parent_attach = attach(J.parent, J.parent_node, J.p_PoJ_P, "parent", n.Phi_Pj, n.Psi_Pj,
                               n.stiff_P, n.e_Pj, n.G_Pj);
      n.pm = static_cast<int>(n.Phi_Pj.cols());
    } else if (J.parent_node >= 0) {
      throw InputError(jname + ": the free joint has no parent body, so no parent_node");
    }
    n.child_attach = attach(J.child, J.child_node, J.p_CoJ_C, "child", n.Phi_Cj, n.Psi_Cj,
                            n.stiff_C, n.e_Cj, n.G_Cj);
    if (k == 0 && n.shape == JointShape::Base6 && J.child_node >= 0)
      throw InputError(jname +
                       ": the free joint moves the base's body frame; child_node must "
                       "not be set");
    if (n.parent_attach)
      nodes_[static_cast<std::size_t>(n.parent)].attached_children.push_back(static_cast<int>(k));

    n.unit->sizes(n.prescribed, n.nqj, n.nuj);
    n.nm = n.flex >= 0 ? flex_[static_cast<std::size_t>(n.flex)].n : 0;
    n.q0 = nq;
    n.u0 = nu;
    n.nq = n.nqj + n.nm;
    n.nu = n.nuj + n.nm;
    nq += n.nq;
    nu += n.nu;
    for (int a = n.parent, via = static_cast<int>(k); a >= 0;
         via = a, a = nodes_[static_cast<std::size_t>(a)].parent)
      if (nodes_[static_cast<std::size_t>(a)].nu > 0) n.speed_ancestors.push_back({a, via});
    total_mass_ += n.mass;
  }
  n_q_ = nq;
  n_u_ = nu;
  // subtree_pass's first terms: visiting nodes last first, the first child to reach a parent is
  // its highest-index one; a node no child reaches starts with its own body.
  for (std::size_t k = nj; k-- > 1;) {
    Node& p = nodes_[static_cast<std::size_t>(nodes_[k].parent)];
    nodes_[k].parent_start = p.sums_start;
    p.sums_start = false;
  }
  for (Node& n : nodes_) {
    n.leaf_rigid = n.sums_start && n.flex < 0 && n.parent >= 0 && !n.parent_attach;
    n.parent_free_base =
        n.parent >= 0 && nodes_[static_cast<std::size_t>(n.parent)].shape == JointShape::Base6;
  }

  // State labels.
  labels_.assign(static_cast<std::size_t>(n_q_ + n_u_), "");
  for (const Node& n : nodes_) {
    const Body& body = system_.bodies[static_cast<std::size_t>(n.body)];
    const std::string& b = body.name;
    const std::string& j = system_.joints[static_cast<std::size_t>(n.joint)].name;
    n.unit->labels(n, n_q_, b, j, labels_);
    for (int l = 0; l < n.nm; ++l) {
      const std::string mode = b + "." + body.flex->mode_names[static_cast<std::size_t>(l)];
      labels_[static_cast<std::size_t>(n.q0 + n.nqj + l)] = mode;
      labels_[static_cast<std::size_t>(n_q_ + n.u0 + n.nuj + l)] = mode + "_rate";
    }
  }

  // Output columns: the pinned ones, then this engine's extras.
  extra0_ = layout_.add_extra("kane.T", "J");
  layout_.add_extra("kane.V", "J");
  for (const char* c : {"kane.H_N.x", "kane.H_N.y", "kane.H_N.z"}) layout_.add_extra(c, "kg m^2/s");
  for (const char* c : {"kane.P_N.x", "kane.P_N.y", "kane.P_N.z"}) layout_.add_extra(c, "kg m/s");
  layout_.add_extra("kane.quat_norm_error", "");

  // Workspace.
  work_.resize(nj);
  prescribed_torque_.assign(nj, 0.0);
  for (auto* v : {&F_C_, &M_J_C_, &F_N_, &M_J_N_}) v->assign(nj, Vector3d::Zero());
  for (NodeWork* w : {&ground_}) {
    w->R_NB.setIdentity();
    w->I_BBo_N.setZero();
    w->W_N.setZero();
    w->V_N.setZero();
    for (Vector3d* v : {&w->p_B0oBo_N, &w->p_B0oOk_N, &w->p_PoOk_N, &w->p_OkBo_N, &w->w_NB_N, &w->v_NBo_N, &w->w_NB_B,
                        &w->w_PC_N, &w->w_NJp_N, &w->v_PC_N, &w->alpha_PC_t_N, &w->alpha_t_N, &w->a_t_N, &w->alpha_N, &w->a_N})
      v->setZero();
  }
  for (std::size_t k = 0; k < nj; ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    w.R_NB.setIdentity();
    // An isotropic rigid body's inertia has the same components in every frame (position_pass
    // does not touch it).
    if (n.flex < 0 && n.inertia == Node::Inertia::Isotropic)
      w.I_BBo_N = n.I_BBo_B;
    else
      w.I_BBo_N.setZero();
    w.W_N.setZero();
    w.V_N.setZero();
    w.v_PC_N.setZero();
    w.alpha_PC_t_N.setZero();
    w.p_B0oBo_N.setZero();
    w.p_B0oOk_N.setZero();
    w.p_PoOk_N.setZero();
    w.p_OkBo_N.setZero();
    w.w_NB_N.setZero();
    w.w_NB_B.setZero();
    w.v_NBo_N.setZero();
    w.w_PC_N.setZero();
    w.w_NJp_N.setZero();
    w.alpha_t_N.setZero();
    w.a_t_N.setZero();
    w.alpha_N.setZero();
    w.a_N.setZero();
    w.m_sub = 0;
    w.s_sub_N.setZero();
    w.J_sub_N.setZero();
    w.F_sub_N.setZero();
    w.M_sub_N.setZero();
    const Eigen::Index pm = n.parent_attach ? n.pm : 0, nm = n.child_attach ? n.nm : 0;
    w.Wp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.Vp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.pp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.hp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.Wm_N = Eigen::Matrix3Xd::Zero(3, nm);
    w.Vm_N = Eigen::Matrix3Xd::Zero(3, nm);
    for (Vector3d* v : {&w.w_att_N, &w.v_att_N, &w.jdot_att_N, &w.w_m_N, &w.v_m_N, &w.jdot_m_N})
      v->setZero();
    w.gP = Eigen::VectorXd::Zero(n.stiff_P ? n.pm : 0);
    w.gC = Eigen::VectorXd::Zero(n.stiff_C ? n.nm : 0);
  }
  flex_work_.resize(flex_.size());
  for (std::size_t f = 0; f < flex_.size(); ++f) {
    const Eigen::Index m = flex_[f].n;
    FlexWork& fw = flex_work_[f];
    fw.c_B.setZero();
    fw.c_N.setZero();
    fw.I_B.setZero();
    for (Eigen::Matrix3Xd* M : {&fw.A_B, &fw.S_N, &fw.A_N, &fw.Ce_B, &fw.pm_N, &fw.hm_N})
      *M = Eigen::Matrix3Xd::Zero(3, m);
    fw.N_B.assign(static_cast<std::size_t>(m), Matrix3d::Zero());
    fw.cdot_N.setZero();
    fw.hdef_N.setZero();
    fw.L_B.setZero();
    const FlexModel& F = flex_[f];
    fw.S_B = F.S;
    fw.Mm = F.Mm;
    fw.bgen = Eigen::VectorXd::Zero(m);
    if (F.stiff) {
      fw.Phit.assign(F.sn.size(), Eigen::Matrix3Xd::Zero(3, m));
      fw.r.assign(F.sn.size(), Vector3d::Zero());
      fw.g.assign(F.sn.size(), Eigen::VectorXd::Zero(m));
    }
  }
  M_ = Eigen::MatrixXd::Zero(n_u_, n_u_);
  f_ = Eigen::VectorXd::Zero(n_u_);
  udot_ = Eigen::VectorXd::Zero(n_u_);
  lambda_.assign(static_cast<std::size_t>(n_u_), -1);
  for (const Node& n : nodes_) {
    if (n.nu == 0) continue;
    int parent_speed = -1;
    if (!n.speed_ancestors.empty()) {
      const Node& a = nodes_[static_cast<std::size_t>(n.speed_ancestors.front().node)];
      parent_speed = a.u0 + a.nu - 1;
    }
    for (int i = 0; i < n.nu; ++i)
      lambda_[static_cast<std::size_t>(n.u0 + i)] = i == 0 ? parent_speed : n.u0 + i - 1;
  }
  q_N_.assign(nj, Quaterniond::Identity());

  // Solver (README.md, "Two solvers"): the speeds on the deepest root-to-leaf path decide.
  std::vector<int> depth(nj, 0);
  for (std::size_t k = 0; k < nj; ++k) {
    const Node& n = nodes_[k];
    depth[k] = n.nu + (n.parent >= 0 ? depth[static_cast<std::size_t>(n.parent)] : 0);
    max_speed_depth_ = std::max(max_speed_depth_, depth[k]);
  }
  const bool rigid = flex_.empty();
  // The order-N solver declines prescribed joints (issue 13): its elimination assumes a free
  // base and a speed for every revolute joint, so a scene with a prescribed joint (inside the
  // tree or as the base) always uses the composite solver, which handles both.
  const bool order_n_ok = rigid && !has_prescribed_ && system_.base_is_free();
  if (solver == KaneSolver::OrderN && rigid && !order_n_ok)
    throw InputError(file + ": the kane engine's order-N solver handles no prescribed joint; use "
                     "the composite solver");
  if (solver == KaneSolver::OrderN && !rigid) {
    std::string flexible;
    for (const Body& b : system_.bodies)
      if (b.flex && flexible.empty()) flexible = b.name;
    throw InputError(file + ": the kane engine's order-N solver handles rigid bodies only (body '" +
                     flexible + "' is flexible); use the composite solver");
  }
  if (solver == KaneSolver::Automatic)
    solver = order_n_ok && max_speed_depth_ >= kOrderNMinDepth ? KaneSolver::OrderN
                                                          : KaneSolver::Composite;
  solver_ = solver;
  // The fused rigid path has a branch for some shapes of speeds (fused_shape, joint_unit.hpp); a
  // scene with any other joint takes the general passes.
  bool fused = true;
  for (const Node& n : nodes_) fused = fused && fused_shape(n.shape);
  rigid_fast_ = solver_ == KaneSolver::Composite && rigid && !has_prescribed_ &&
                system_.base_is_free() && fused;
  for (const Joint& J : system_.joints)
    has_potential_ = has_potential_ || J.stiffness != 0 || J.stiffness2 != 0;
  has_potential_ = has_potential_ || !flex_.empty();
  if (solver_ == KaneSolver::OrderN) {
    art_.resize(nj);
    for (ArticulatedWork& a : art_) {
      for (Matrix3d* M : {&a.Iww_N, &a.Iwv_N, &a.Ivv_N, &a.U_M_N, &a.U_F_N, &a.D_inv}) M->setZero();
      for (Vector3d* v : {&a.Z_M_N, &a.Z_F_N, &a.g, &a.dalpha_N, &a.da_Ok_N}) v->setZero();
    }
  }
  // The environment (gravity.cpp): last, since an orbit's O is the CM of the packed initial state.
  init_environment();
}

const char* kane_solver_name(KaneSolver s) {
  switch (s) {
    case KaneSolver::Automatic:
      return "automatic";
    case KaneSolver::Composite:
      return "composite";
    case KaneSolver::OrderN:
      return "order-n";
  }
  return "?";
}

}  // namespace crossdyn::kane
