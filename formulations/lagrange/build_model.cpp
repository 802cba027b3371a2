// Construction of the Lagrange engine: the System checked (validate_flex.cpp) and turned into the
// immutable Model (model.hpp: coordinates, labels, tree structure), and the Workspace
// (workspace.hpp) sized once. Coordinates: README.md, "Coordinates".
#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/rotation.hpp"
#include "core/scene/topology.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/joints/joint_unit.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "formulations/lagrange/messages.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

LagrangeEngine::LagrangeEngine(const System& system, const EngineOptions& options) {
  auto m = std::make_unique<Model>();
  const std::string where = (system.file.empty() ? system.name : system.file) + ": ";
  // The tree (one free joint first, every parent the child of an earlier joint, one joint per
  // body, indices in range): the one public check, core/scene/topology.hpp.
  check_topology(system);
  if (!(options.test_inertia_scale > 0.0) || !std::isfinite(options.test_inertia_scale))
    throw InputError(where + "engine option test_inertia_scale must be positive, got " +
                     format_number(options.test_inertia_scale));
  // Test hook (EngineOptions::test_damper_scale): the joint and modal dampers of the equations of
  // motion are the scene's times this factor, folded into the model's coefficients here (untouched
  // when it is 1: the same floating-point operations); the power column P keeps the scene's
  // (Model::BodyM::D_scene, Model::JointM::damping_scene).
  const double damper_scale = options.test_damper_scale;
  if (!(damper_scale >= 0.0) || !std::isfinite(damper_scale))
    throw InputError(where + "engine option test_damper_scale must be finite and >= 0, got " +
                     format_number(damper_scale));
  validate_flex(system, where);
  // The environment (issue 28; gravity.cpp) and the test hook on the gravity-gradient torques.
  if (!std::isfinite(options.test_gravity_gradient_sign))
    throw InputError(where + "engine option test_gravity_gradient_sign must be finite, got " +
                     format_number(options.test_gravity_gradient_sign));
  m->environment = system.environment;
  m->gravity = !system.environment.none();
  m->orbit = system.environment.orbit();
  m->gg_sign = options.test_gravity_gradient_sign;
  for (const Body& b : system.bodies) {
    Model::BodyM bm;
    bm.name = b.name;
    bm.mass = b.mass;
    bm.I_BBo_B = b.I_BBo_B * options.test_inertia_scale;
    bm.torque_frame = b.torque_frame;
    bm.torque = b.torque;
    if (b.flex) {
      // The flexible body's mass and inertia are its node sums (docs/flexible-bodies.md).
      bm.flex = static_cast<int>(m->flex.size());
      m->flex.emplace_back(*b.flex, options.test_inertia_scale);
      bm.D_scene = m->flex.back().Dmp;
      if (damper_scale != 1.0) m->flex.back().Dmp *= damper_scale;
      bm.nm = b.flex->modes();
      bm.mass = m->flex.back().m;
      bm.I_BBo_B = m->flex.back().rigid_inertia();
      m->max_modes = std::max(m->max_modes, bm.nm);
    }
    m->total_mass += bm.mass;
    m->bodies.push_back(std::move(bm));
  }
  int i0 = 0;
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    Model::JointM jm;
    jm.name = J.name;
    jm.type = J.type;
    const JointUnit& unit = joint_unit(J.type);
    jm.unit = &unit;
    jm.parent = J.parent;
    jm.child = J.child;
    jm.i0 = i0;
    // A prescribed revolute or prismatic joint keeps its coordinate in q* (Joint::dof() is 0: not
    // in the state).
    jm.dof = unit.dof;
    jm.translations = unit.translations;
    if (unit.prescribable && J.prescribed) {
      jm.prescribed = true;
      jm.motion = *J.prescribed;
      jm.angle0 = J.angle0;
      m->prescribed_joints.push_back(static_cast<int>(j));
    }
    Model::BodyM& child_body = m->bodies[static_cast<std::size_t>(J.child)];
    jm.size = jm.dof + child_body.nm;
    if (child_body.flex >= 0) child_body.e0 = i0 + jm.dof;
    jm.p_PoJ_P = J.p_PoJ_P;
    jm.p_CoJ_C = J.p_CoJ_C;
    jm.q_PJ0 = J.q_PJ0.normalized();
    jm.R_PJ0 = jm.q_PJ0.toRotationMatrix();
    jm.axis_J = jm.R_PJ0.transpose() * J.axis_P.normalized();
    const Eigen::Matrix3d K = rot::skew(jm.axis_J);
    jm.C0 = jm.R_PJ0;
    jm.C1 = jm.R_PJ0 * K;
    jm.C2 = jm.R_PJ0 * K * K;
    // What its coordinates do (joint_unit.hpp; README.md "Kinematics").
    jm.absolute = unit.absolute_attitude;
    jm.relative_euler = unit.euler_offset >= 0 && !unit.absolute_attitude;
    jm.axis_rotations = unit.axis_rotations;
    jm.slides = unit.slides;
    jm.scalar_coordinates = unit.axis_rotations + unit.slides;
    jm.axis_last_J = jm.axis_J;
    if (unit.axis_rotations == 2) {
      // R_PC = Rot(axis_P, a1) Rot(axis2_P, a2) R_PJ0 = R_PJ0 Rot(axis_J, a1) Rot(axis2_J, a2),
      // since Rot(a, t) R = R Rot(R^T a, t) (system.hpp, universal).
      jm.axis2_J = jm.R_PJ0.transpose() * J.axis2_P.normalized();
      jm.D1 = rot::skew(jm.axis2_J);
      jm.D2 = jm.D1 * jm.D1;
      jm.b1 = jm.D1 * jm.axis_J;
      jm.b2 = jm.D2 * jm.axis_J;
      jm.axis_last_J = jm.axis2_J;
      // |n_2 x n_1| = sin of the angle between the axes: parallel axes make M singular.
      if (!(jm.b1.norm() > 1e-6))
        throw InputError(where + "joints: joint '" + J.name +
                         "': the universal joint's two axes are parallel (or not finite)");
    }
    if (unit.slides > 0) jm.slide_P = J.axis_P.normalized();
    unit.loads(J, jm);
    jm.damping_scene = jm.damping;
    if (damper_scale != 1.0)
      for (double& c : jm.damping) c *= damper_scale;
    if (unit.at_nodes && J.parent_node >= 0) {
      const FlexNode& nd =
          system.bodies[static_cast<std::size_t>(J.parent)].flex->nodes[static_cast<std::size_t>(
              J.parent_node)];
      jm.parent_node = J.parent_node;
      jm.p_PoJ_P = nd.p_BoNi_B;
      jm.Phi_P = nd.Phi_B;
      jm.Psi_P = nd.Psi_B;
      if (system.bodies[static_cast<std::size_t>(J.parent)].flex->geometric_stiffening &&
          nd.G.size() > 0) {
        jm.stiff_P = true;
        jm.e_P = nd.e_B;
        jm.Gs_P = 0.5 * (nd.G + nd.G.transpose());
      }
    }
    if (unit.at_nodes && J.child_node >= 0) {
      const FlexNode& nd =
          system.bodies[static_cast<std::size_t>(J.child)].flex->nodes[static_cast<std::size_t>(
              J.child_node)];
      jm.child_node = J.child_node;
      jm.p_CoJ_C = nd.p_BoNi_B;
      jm.Phi_C = nd.Phi_B;
      jm.Psi_C = nd.Psi_B;
      if (system.bodies[static_cast<std::size_t>(J.child)].flex->geometric_stiffening &&
          nd.G.size() > 0) {
        jm.stiff_C = true;
        jm.e_C = nd.e_B;
        jm.Gs_C = 0.5 * (nd.G + nd.G.transpose());
      }
    }
    jm.rigid_point = jm.parent_node < 0 && jm.child_node < 0 && jm.slides == 0;
    // The twist pass turns the first of two axis rotations only on its short path (kinematics.hpp).
    if (jm.axis_rotations > 1 && !jm.rigid_point)
      throw InputError(where + "joints: joint '" + J.name +
                       "': two axis rotations need a rigid joint point (no node, no slide)");
    jm.has_spring = false;
    for (double k : jm.stiffness) jm.has_spring = jm.has_spring || k != 0.0;
    const std::string& child = system.bodies[static_cast<std::size_t>(J.child)].name;
    if (unit.euler_offset >= 0) {
      jm.euler_set = static_cast<int>(m->euler_sets.size());
      Model::EulerSetM es;
      es.i0 = i0 + unit.euler_offset;
      unit.euler_set(J.name, child, es);
      m->euler_sets.push_back(es);
    }
    // State labels: q* block (joint coordinates, then the child's modal coordinates).
    unit.coordinate_labels(J.name, child, m->labels);
    if (const auto& f = system.bodies[static_cast<std::size_t>(J.child)].flex)
      for (const std::string& mode : f->mode_names) m->labels.push_back(child + "." + mode);
    i0 += jm.size;
    m->joints.push_back(std::move(jm));
  }
  m->n = i0;
  for (Model::JointM& J : m->joints)
    if (J.parent_node >= 0) J.parent_e0 = m->bodies[static_cast<std::size_t>(J.parent)].e0;
  for (Model::JointM& J : m->joints)
    if (J.child_node >= 0) J.child_e0 = m->bodies[static_cast<std::size_t>(J.child)].e0;
  // Tree structure: subtrees, the joint of every coordinate, each body's supporting pi'.
  const std::size_t nj = m->joints.size();
  for (std::size_t j = 0; j < nj; ++j) {
    m->all_joints.push_back(static_cast<int>(j));
    for (int i = 0; i < m->joints[j].size; ++i) m->coordinate_joint.push_back(static_cast<int>(j));
  }
  std::vector<int> joint_of_body(m->bodies.size(), -1);
  for (std::size_t j = 0; j < nj; ++j)
    joint_of_body[static_cast<std::size_t>(m->joints[j].child)] = static_cast<int>(j);
  for (std::size_t j = 0; j < nj; ++j) {
    cancel::poll();
    // Joint k is below j when walking up from k's child reaches j's child.
    for (std::size_t k = j; k < nj; ++k) {
      int b = m->joints[k].child;
      while (b >= 0 && b != m->joints[j].child)
        b = m->joints[static_cast<std::size_t>(joint_of_body[static_cast<std::size_t>(b)])].parent;
      if (b >= 0) m->joints[j].subtree.push_back(static_cast<int>(k));
    }
  }
  m->support.resize(m->bodies.size());
  for (std::size_t b = 0; b < m->bodies.size(); ++b) {
    for (int bb = static_cast<int>(b); bb >= 0;) {
      const Model::JointM& J =
          m->joints[static_cast<std::size_t>(joint_of_body[static_cast<std::size_t>(bb)])];
      for (int i = 0; i < J.size; ++i) m->support[b].push_back(J.i0 + i);
      bb = J.parent;
    }
    std::sort(m->support[b].begin(), m->support[b].end());
  }
  for (std::size_t j = 0; j < nj; ++j) {
    const Joint& J = system.joints[j];
    const std::string& child = system.bodies[static_cast<std::size_t>(J.child)].name;
    m->joints[j].unit->rate_labels(J.name, child, m->labels);
    if (const auto& f = system.bodies[static_cast<std::size_t>(J.child)].flex)
      for (const std::string& mode : f->mode_names)
        m->labels.push_back(child + "." + mode + "_rate");
  }
  m->set_of_coordinate.assign(static_cast<std::size_t>(m->n), -1);
  for (std::size_t s = 0; s < m->euler_sets.size(); ++s)
    for (int a = 0; a < 3; ++a)
      m->set_of_coordinate[static_cast<std::size_t>(m->euler_sets[s].i0 + a)] = static_cast<int>(s);
  // T and V do not depend on the free base's position (the first three coordinates). A
  // prescribed base's angle is kept: its derivative enters the joint torque.
  m->base_free = system.base_is_free();
  m->base_set = m->base_free ? m->joints[0].euler_set : -1;
  for (int r = m->base_free ? 3 : 0; r < m->n; ++r) m->gradient_dirs.push_back(r);
  m->has_prescribed = !m->prescribed_joints.empty();
  m->state_of.assign(static_cast<std::size_t>(m->n), -1);
  for (int i = 0; i < m->n; ++i) {
    const Model::JointM& J = m->joints[static_cast<std::size_t>(m->coordinate_joint[static_cast<std::size_t>(i)])];
    if (J.prescribed && i == J.i0) continue;
    m->state_of[static_cast<std::size_t>(i)] = static_cast<int>(m->free_index.size());
    m->free_index.push_back(i);
  }
  m->nf = static_cast<int>(m->free_index.size());
  // A prescribed base has no linear momentum of its own to choose (docs/prescribed-motion.md).
  m->zero_linear_momentum = system.zero_linear_momentum && m->base_free;
  m->rechart = options.rechart;
  m->layout = OutputLayout(system);
  m->recharts_column = m->layout.add_extra("lagrange.recharts", "");

  // Workspace, sized once.
  auto w = std::make_unique<Workspace>();
  const int n = m->n;
  const int nb = static_cast<int>(m->bodies.size());
  const std::size_t ns = m->euler_sets.size();
  w->chart.assign(ns, kDefaultChart);
  w->last_a2.assign(ns, 0.0);
  w->A.assign(ns, Eigen::Matrix3d::Identity());
  w->A_dual.assign(ns, Mat3<Dual<2>>::Identity());
  w->B.assign(ns, Eigen::Matrix3d::Identity());
  w->k0.resize(*m);
  w->k1.resize(*m);
  size_gradient_workspace(*m, *w);
  w->Xi.assign(static_cast<std::size_t>(nb), Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, n));
  w->Xi_dot = w->Xi;
  w->fi0.resize(static_cast<std::size_t>(nb));
  for (std::size_t b = 0; b < m->bodies.size(); ++b)
    w->fi0[b].resize(m->bodies[b].nm, m->bodies[b].flex >= 0 &&
                                          m->flex[static_cast<std::size_t>(m->bodies[b].flex)].stiff);
  w->he1.assign(static_cast<std::size_t>(m->max_modes), Dual<1>(0.0));
  w->he0 = Eigen::VectorXd::Zero(m->max_modes);
  w->unit = Eigen::VectorXd::Zero(m->max_modes);
  w->q_NB.assign(static_cast<std::size_t>(nb), Eigen::Quaterniond::Identity());
  for (auto* v : {&w->dP_N, &w->dK_N, &w->T_N, &w->P_b, &w->h_b, &w->s_b})
    v->assign(static_cast<std::size_t>(nb), Eigen::Vector3d::Zero());
  for (auto* v : {&w->F_N, &w->M_J_N, &w->r_J_N})
    v->assign(m->joints.size(), Eigen::Vector3d::Zero());
  w->M = Eigen::MatrixXd::Zero(n, n);
  w->U = Eigen::MatrixXd::Zero(n, n);
  w->DX = Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, n);
  w->Y = w->DX;
  w->Yd = w->DX;
  for (Eigen::VectorXd* v :
       {&w->u, &w->qdot, &w->p, &w->Mdot_u, &w->hamel, &w->dL, &w->N, &w->f, &w->udot, &w->seed,
        &w->inv_diag})
    *v = Eigen::VectorXd::Zero(n);
  w->xf = Eigen::VectorXd::Zero(2 * n);
  w->Mff = Eigen::MatrixXd::Zero(m->nf, m->nf);
  w->Uff = w->Mff;
  w->bf = Eigen::VectorXd::Zero(m->nf);
  w->inv_diag_f = w->bf;
  w->torque = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m->prescribed_joints.size()));
  if (m->gravity) {
    for (auto* v : {&w->p_g_N, &w->F_g_N, &w->M_g_N})
      v->assign(static_cast<std::size_t>(nb), Eigen::Vector3d::Zero());
    w->Q_g = Eigen::VectorXd::Zero(m->max_modes);
    if (m->orbit) {
      w->fi_g.resize(static_cast<std::size_t>(nb));
      for (std::size_t b = 0; b < m->bodies.size(); ++b)
        w->fi_g[b].resize(m->bodies[b].nm,
                          m->bodies[b].flex >= 0 &&
                              m->flex[static_cast<std::size_t>(m->bodies[b].flex)].stiff);
      w->eta_g.assign(static_cast<std::size_t>(m->max_modes), Dual<1>(0.0));
    }
  }
  m->tangent = true;  // every system the constructor accepts (tangent.cpp)
  Model* const model = m.get();
  model_ = std::move(m);
  ws_ = std::move(w);
  if (model->orbit) {
    // O, the system's CM at t = 0 (core/system.hpp, Environment), from the scene's initial state in
    // this engine's own coordinates: the double pose pass and the first mass moments, as the
    // output column p_NoScm_N (outputs.cpp). Set once, here; the Model is immutable after.
    std::vector<double> x0(static_cast<std::size_t>(state_size()));
    pack(TreeState::initial(system), x0.data());
    kinetic_energy_full(expand(0.0, x0.data()));  // the pose pass into k0
    const Kin<double>& k = ws_->k0;
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for (std::size_t b = 0; b < model->bodies.size(); ++b) {
      s += model->bodies[b].mass * k.p_NoBo_N[b];
      if (model->bodies[b].flex >= 0) s += k.R_NB[b] * k.fi[b].s;
    }
    model->p_NoO_N = s / model->total_mass;
  }
}

}  // namespace crossdyn::lagrange
