// The complex step of one output row (issue 27; newton_euler.cpp, output_row_tangent()): what
// RowWriter (core/output_layout.hpp) writes, on Cx = std::complex<double> (scalar.hpp), with the
// same method names, so that the templated output code (newton_euler.cpp, write_outputs(); the
// joint units' output verbs) runs on RowWriter for the run and on this writer for the tangent.
// Each value's imaginary part over h goes to drow (Martins, Sturdza & Alonso 2003, ACM TOMS 29(3):
// d/de f(x + e dx) = Im f(x + i h dx) / h + O(h^2)); the values themselves are output_row()'s.
// RowWriter's own nonlinear steps are mirrored analytically: the canonical sign of q (the sign
// of the value output_row() wrote: with qw at round-off from 0 the double and complex paths may
// round it to opposite signs), |H| = sqrt(H . H), and on an orbit
// roll, pitch, yaw (core/orbit.cpp's roll_pitch_yaw, its branches on the real parts) and w_OB_B.
#pragma once

#include "core/output_layout.hpp"
#include "formulations/newton_euler/scalar.hpp"

namespace crossdyn::newton_euler {

class CxRowWriter {
 public:
  // Starts drow (layout.size() values) as NaN, like RowWriter: a column not written shows. row:
  // the values output_row() wrote at the same state (the sign of each quaternion is read there).
  CxRowWriter(const OutputLayout& layout, const double* row, double* drow, double h);

  void time(double t);  // drow[0] = 0; t kept for the orbit columns (call first)
  void body(int b, const Vec3<Cx>& w_NB_B, const Quat<Cx>& q_NB);
  void revolute(int joint, Cx angle, Cx rate);
  void joint_torque(int joint, Cx torque);
  void spherical(int joint, const Vec3<Cx>& w_PC_C);
  void prismatic(int joint, Cx position, Cx rate);
  void universal(int joint, Cx angle1, Cx angle2, Cx rate1, Cx rate2);
  void modal(int b, const Eigen::VectorXcd& eta, const Eigen::VectorXcd& eta_rate);
  void momentum(const Vec3<Cx>& H_Scm_N);
  void energy(Cx E) { put(layout_.E(), E); }
  void body_position(int b, const Vec3<Cx>& p_NoBo_N);
  void system_cm(const Vec3<Cx>& p_NoScm_N);
  void joint_load(int joint, const Vec3<Cx>& F_C, const Vec3<Cx>& M_J_C);
  void power(Cx P) { put(layout_.P(), P); }
  void external_moment(const Vec3<Cx>& M_Scm_N);
  void jacobi(Cx J) { put(layout_.J(), J); }
  void extra(int column, Cx value) { put(column, value); }

 private:
  void put(int column, const Cx& v) { drow_[column] = v.imag() / h_; }
  const OutputLayout& layout_;
  const double* row_;
  double* drow_;
  double h_;
  double t_ = 0;
};

}  // namespace crossdyn::newton_euler
