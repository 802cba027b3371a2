// The spherical joint: the joint point only (joint_constraints.hpp, "spherical: rows 0-2 only", no
// rotation rows). Its unit (joint_unit.hpp) implements, from newton_euler.hpp and core/system.hpp,
// the relative attitude q_J and angular velocity w_PC_C (= w_FG_G) of the state and outputs, the
// spring (about the rotation vector of q_PJ0^* q_FG), damper and motor torque, and wdot_PC_C.
#include "formulations/newton_euler/joints/joint_unit.hpp"

#include "core/rotation.hpp"

namespace crossdyn::newton_euler {

using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

void model(const Joint& /*joint*/, JointModel& m) { m.rows = 3; }

// Spring, damper and motor in G (core/system.hpp), on the child-side frame, in P.
// The rotation vector of a unit quaternion (core's rot::rotation_vector on double; on Cx the same
// function, its branches on the real part: the canonical sign w >= 0, the series 2 v / w below
// |v| = 1e-8, else v 2 atan2(|v|, w) / |v| with |v| = sqrt(v . v), analytic).
template <class S>
Vec3<S> rotation_vector(const Quat<S>& q_in) {
  if constexpr (kIsReal<S>) {
    return rot::rotation_vector(q_in);
  } else {
    const Quat<S> q = real_part(q_in.w()) < 0 ? Quat<S>(-q_in.w(), -q_in.x(), -q_in.y(), -q_in.z()) : q_in;
    const Vec3<S> v = q.vec();
    using std::sqrt;
    const S s = sqrt(tsquared_norm<S>(v));
    if (real_part(s) < 1e-8) return 2.0 * v / q.w();
    const S angle = 2.0 * tatan2(s, q.w());
    return v * (angle / s);
  }
}

template <class S>
bool load(const Joint& J, const JointModel& m, const JointKinematicsT<S>& jk,
          const JointCoordsT<S>& /*coords*/, double t, Vec3<S>& T_P, Vec3<S>& /*F_P*/) {
  Vec3<S> tau_G = -m.damping * jk.w_FG_G;
  if (J.stiffness != 0)
    tau_G -= J.stiffness * rotation_vector<S>(Quat<S>(m.q_PJ0.template cast<S>().conjugate() * jk.q_FG));
  if (!J.motor_spherical.empty()) tau_G += J.motor_spherical.value(t);
  const Vec3<S> T_C = m.C.modes > 0 ? Vec3<S>(jk.G.E * tau_G) : tau_G;
  T_P = jk.R_PC * T_C;
  return true;
}

template <class S>
void pack_t(const JointModel& /*m*/, const JointStateT<S>& js, Quat<S>& q_J, Vec3<S>& w_FG_G,
            Vec3<S>& /*r_F*/, Vec3<S>& /*v_F*/) {
  S norm;
  q_J = unit_quaternion(js.q_J, norm);
  w_FG_G = js.w_PC_C;
}

void pack(const JointModel& m, const TreeState::JointState& js, Quaterniond& q_J,
          Vector3d& w_FG_G, Vector3d& r_F, Vector3d& v_F, JointCoords& /*coords_ref*/) {
  pack_t<double>(m, JointStateT<double>{js.angle, js.rate, js.angle2, js.rate2, js.q_J, js.w_PC_C},
                 q_J, w_FG_G, r_F, v_F);
}

template <class S>
void accelerations_t(const Joint& /*J*/, const JointModel& /*m*/, const JointAccelInputsT<S>& in,
                     double /*t*/, JointAccelT<S>& a) {
  const JointKinematicsT<S>& jk = in.jk;
  const Vec3<S> w_F_G = jk.R_FG.transpose() * jk.w_F;
  a.wdot_PC_C = in.wdot_G - jk.R_FG.transpose() * in.wdot_F + tcross<S>(jk.w_FG_G, w_F_G);
}

void accelerations(const Joint& J, const JointModel& m, const JointAccelInputs& in, double t,
                   TreeAccel& a, int j) {
  JointAccelT<double> aj;
  accelerations_t<double>(J, m, in, t, aj);
  a.wdot_PC_C[static_cast<std::size_t>(j)] = aj.wdot_PC_C;
}

// Every spherical joint is covered by the tangent.
bool covers(const Joint& /*J*/) { return true; }

template <class S>
void potential_t(const Joint& J, const JointModel& m, const JointKinematicsT<S>& jk,
                 const JointCoordsT<S>& /*coords*/, S& e) {
  const Vec3<S> phi = rotation_vector<S>(Quat<S>(m.q_PJ0.template cast<S>().conjugate() * jk.q_FG));
  e += 0.5 * J.stiffness * tsquared_norm<S>(phi);
}

void potential(const Joint& J, const JointModel& m, const JointKinematics& jk,
               const JointCoords& coords, double& e) {
  potential_t<double>(J, m, jk, coords, e);
}

template <class W, class S>
void output_t(W& out, int j, const Joint& /*J*/, const JointModel& /*m*/, const JointKinematicsT<S>& jk,
              const JointCoordsT<S>& /*coords*/, S /*torque*/, double /*t*/) {
  out.spherical(j, jk.w_FG_G);
}

void output(RowWriter& out, int j, const Joint& J, const JointModel& m, const JointKinematics& jk,
            const JointCoords& coords, double torque, double t) {
  output_t<RowWriter, double>(out, j, J, m, jk, coords, torque, t);
}

// Power of the motor and damper (the scene's values): the torque tau_G on the child-side frame G
// and its reaction on F work at w_FG_G (= the output w_PC_C): (motor - damping w_PC_C) . w_PC_C;
// the spring's part is -dV/dt (in E).
template <class S>
S power_t(const Joint& J, const JointModel& /*m*/, const JointKinematicsT<S>& jk, S /*torque*/, double t) {
  Vec3<S> tau_G = -J.damping * jk.w_FG_G;
  if (!J.motor_spherical.empty()) tau_G += J.motor_spherical.value(t);
  return tdot<S>(tau_G, jk.w_FG_G);
}

double power(const Joint& J, const JointModel& m, const JointKinematics& jk, double torque, double t) {
  return power_t<double>(J, m, jk, torque, t);
}

const JointVerbsCx kCx{covers,           nullptr,  nullptr,    nullptr,
                       nullptr,          load<Cx>, pack_t<Cx>, accelerations_t<Cx>,
                       potential_t<Cx>,  output_t<CxRowWriter, Cx>, power_t<Cx>};

}  // namespace

const JointUnit kSphericalJoint{"spherical", model,   nullptr,      nullptr,   nullptr,
                                nullptr,     nullptr, load<double>, pack,      accelerations,
                                potential,   output,  nullptr,      power,     &kCx};

}  // namespace crossdyn::newton_euler
