// CxRowWriter (cx_row_writer.hpp): RowWriter's columns on the complex step.
#include "formulations/newton_euler/cx_row_writer.hpp"

#include "core/orbit.hpp"

#include <cmath>
#include <limits>

namespace crossdyn::newton_euler {

namespace {

// core/orbit.cpp's roll_pitch_yaw on Cx: R = Rz(y) Ry(p) Rx(r), pitch = asin(-R(2,0)) (clamped to
// [-1, 1] on the real part: a clamped value has no variation), roll and yaw by atan2; the gimbal
// lock branch (|sin p| > 1 - 1e-12) chosen on the real part, as there. asin's complex step is its
// value at the real part and the imaginary part times 1 / sqrt(1 - x^2).
Vec3<Cx> roll_pitch_yaw_cx(const Mat3<Cx>& R) {
  Cx sp = -R(2, 0);
  if (sp.real() > 1.0) sp = Cx(1.0);
  if (sp.real() < -1.0) sp = Cx(-1.0);
  const double spr = sp.real();
  const Cx pitch(std::asin(spr), sp.imag() / std::sqrt(1.0 - spr * spr));
  if (std::abs(spr) > 1.0 - 1e-12) return Vec3<Cx>(Cx(0.0), pitch, tatan2(-R(0, 1), R(1, 1)));
  return Vec3<Cx>(tatan2(R(2, 1), R(2, 2)), pitch, tatan2(R(1, 0), R(0, 0)));
}

}  // namespace

CxRowWriter::CxRowWriter(const OutputLayout& layout, const double* row, double* drow, double h)
    : layout_(layout), row_(row), drow_(drow), h_(h) {
  for (std::size_t i = 0; i < layout.size(); ++i) drow_[i] = std::numeric_limits<double>::quiet_NaN();
}

void CxRowWriter::time(double t) {
  t_ = t;
  drow_[0] = 0.0;  // the time column does not vary with the state
}

void CxRowWriter::body(int b, const Vec3<Cx>& w_NB_B, const Quat<Cx>& q_NB) {
  const int w = layout_.body_w(b);
  for (int i = 0; i < 3; ++i) put(w + i, w_NB_B(i));
  // RowWriter's qw >= 0: the sign of the value written in row (q or -q, whichever it is).
  const double dot = row_[w + 3] * q_NB.w().real() + row_[w + 4] * q_NB.x().real() +
                     row_[w + 5] * q_NB.y().real() + row_[w + 6] * q_NB.z().real();
  const double s = dot < 0 ? -1.0 : 1.0;
  put(w + 3, s * q_NB.w());
  put(w + 4, s * q_NB.x());
  put(w + 5, s * q_NB.y());
  put(w + 6, s * q_NB.z());
  if (layout_.lvlh(b) >= 0) {  // R_OB = R_NO^T R_NB at the row's time (core/orbit.hpp)
    const OrbitFrame o = orbit_frame(layout_.environment(), t_);
    const Mat3<Cx> R_NB = q_NB.toRotationMatrix();
    const Vec3<Cx> a = roll_pitch_yaw_cx(Mat3<Cx>(o.R_NO.transpose() * R_NB));
    const Vec3<Cx> w_OB_B = w_NB_B - R_NB.transpose() * o.w_NO_N;
    for (int i = 0; i < 3; ++i) {
      put(layout_.lvlh(b) + i, a(i));
      put(layout_.lvlh(b) + 3 + i, w_OB_B(i));
    }
  }
}

void CxRowWriter::revolute(int joint, Cx angle, Cx rate) {
  put(layout_.joint_first(joint), angle);
  put(layout_.joint_first(joint) + 1, rate);
}

void CxRowWriter::joint_torque(int joint, Cx torque) { put(layout_.joint_first(joint) + 2, torque); }

void CxRowWriter::spherical(int joint, const Vec3<Cx>& w_PC_C) {
  for (int i = 0; i < 3; ++i) put(layout_.joint_first(joint) + i, w_PC_C(i));
}

void CxRowWriter::prismatic(int joint, Cx position, Cx rate) {
  put(layout_.joint_first(joint), position);
  put(layout_.joint_first(joint) + 1, rate);
}

void CxRowWriter::universal(int joint, Cx angle1, Cx angle2, Cx rate1, Cx rate2) {
  const int r = layout_.joint_first(joint);
  put(r, angle1);
  put(r + 1, angle2);
  put(r + 2, rate1);
  put(r + 3, rate2);
}

void CxRowWriter::modal(int b, const Eigen::VectorXcd& eta, const Eigen::VectorXcd& eta_rate) {
  const int r = layout_.modal_first(b);
  const auto n = static_cast<int>(eta.size());
  for (int k = 0; k < n; ++k) put(r + k, eta(k));
  for (int k = 0; k < n; ++k) put(r + n + k, eta_rate(k));
}

// |H| = sqrt(H . H): analytic away from H = 0, its tangent H . dH / |H|. At H = 0 exactly (a
// state at rest) |H| has only one-sided derivatives, |dH| and -|dH|: the column's tangent is
// written as 0, the limit of the symmetric difference quotient (|e dH| - |-e dH|) / 2e, as a
// central difference of output_row() finds it; Hx, Hy, Hz carry the variation.
void CxRowWriter::momentum(const Vec3<Cx>& H_Scm_N) {
  const bool at_zero = H_Scm_N.real().isZero(0.0);
  put(layout_.H(), at_zero ? Cx(0.0) : std::sqrt(tsquared_norm<Cx>(H_Scm_N)));
  for (int i = 0; i < 3; ++i) put(layout_.H_vector() + i, H_Scm_N(i));
}

void CxRowWriter::body_position(int b, const Vec3<Cx>& p_NoBo_N) {
  for (int i = 0; i < 3; ++i) put(layout_.body_position(b) + i, p_NoBo_N(i));
}

void CxRowWriter::system_cm(const Vec3<Cx>& p_NoScm_N) {
  for (int i = 0; i < 3; ++i) put(layout_.cm() + i, p_NoScm_N(i));
}

void CxRowWriter::joint_load(int joint, const Vec3<Cx>& F_C, const Vec3<Cx>& M_J_C) {
  const int r = layout_.joint_load(joint);
  for (int i = 0; i < 3; ++i) {
    put(r + i, F_C(i));
    put(r + 3 + i, M_J_C(i));
  }
}

void CxRowWriter::external_moment(const Vec3<Cx>& M_Scm_N) {
  for (int i = 0; i < 3; ++i) put(layout_.external_moment() + i, M_Scm_N(i));
}

}  // namespace crossdyn::newton_euler
