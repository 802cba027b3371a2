// Euler-angle charts of SO(3) for the Lagrange engine (internal header).
//
// A chart is one of the six Tait-Bryan sequences (i, j, k), three distinct axes (0 = x, 1 = y,
// 2 = z), with body-fixed (intrinsic) rotations:
//   R(a) = R_i(a1) R_j(a2) R_k(a3)                      (Kane, Likins & Levinson 1983, Sec. 1.7;
//                                                         Wertz 1978, App. E)
// where R_m(a) is the rotation by angle a about axis m. It takes child (body) components to parent
// components: for the base R = R_NB, for a spherical joint R = R_J (the paper's theta_1j, theta_2j,
// Eq. 15). The default chart is the aerospace 3-2-1 sequence (yaw a1 about z, pitch a2 about y,
// roll a3 about x).
//
// Kinematics: the angular velocity of the rotated frame, in that frame, is linear in the rates,
//   w = A(a) a',   A = [ R_k(a3)^T R_j(a2)^T e_i,  R_k(a3)^T e_j,  e_k ]           (columns)
// (the paper's d(pi) = A dq*, Eqs. 16-18), and det A = -+cos a2: the chart is singular ("gimbal
// lock") where the middle angle is +-90 deg, i.e. where the rotated axis e_k lines up with the
// parent axis e_i. There |R(i, k)| = |sin a2| = 1.
//
// Inverse (angles of a given rotation), with eps = +1 for a cyclic (i, j, k) and -1 otherwise:
//   a2 = atan2(eps R(i,k), sqrt(R(i,i)^2 + R(i,j)^2)),
//   a1 = atan2(-eps R(j,k), R(k,k)),   a3 = atan2(-eps R(i,j), R(i,i)).
// Among the six sequences some |R(i,k)| is at most 1/sqrt(2) (each row of R is a unit vector, so at
// most one off-diagonal entry per row exceeds 1/sqrt(2)): the best chart has |a2| <= 45 deg.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cmath>

#include "formulations/lagrange/autodiff.hpp"

namespace crossdyn::lagrange {

struct EulerSequence {
  int i, j, k;       // axes of the first, second and third rotation
  const char* name;  // "3-2-1" (axes numbered 1 = x, 2 = y, 3 = z)
  int eps() const { return (j - i + 3) % 3 == 1 ? 1 : -1; }
};

// Index 0 is the default chart.
inline constexpr std::array<EulerSequence, 6> kSequences{{{2, 1, 0, "3-2-1"},
                                                          {0, 1, 2, "1-2-3"},
                                                          {1, 2, 0, "2-3-1"},
                                                          {2, 0, 1, "3-1-2"},
                                                          {0, 2, 1, "1-3-2"},
                                                          {1, 0, 2, "2-1-3"}}};
inline constexpr int kDefaultChart = 0;

// Rotation by angle a about coordinate axis m (active: R v turns v by a about e_m).
template <class S>
Mat3<S> axis_rotation(int m, const S& a) {
  using std::cos;
  using std::sin;
  const S c = cos(a), s = sin(a);
  const int p = (m + 1) % 3, r = (m + 2) % 3;
  Mat3<S> R = Mat3<S>::Zero();
  R(m, m) = S(1.0);
  R(p, p) = c;
  R(r, r) = c;
  R(p, r) = -s;
  R(r, p) = s;
  return R;
}

// M <- R_m(a) M for c = cos a, s = sin a: only the rows m + 1 and m + 2 (mod 3) change.
template <class S>
void rotate_rows(int m, const S& c, const S& s, Mat3<S>& M) {
  const int p = (m + 1) % 3, r = (m + 2) % 3;
  for (int col = 0; col < 3; ++col) {
    const S Mp = M(p, col), Mr = M(r, col);
    M(p, col) = c * Mp - s * Mr;
    M(r, col) = s * Mp + c * Mr;
  }
}

// R(a) = R_i(a1) R_j(a2) R_k(a3), built from the right by two sparse row rotations.
template <class S>
Mat3<S> euler_rotation(const EulerSequence& q, const S& a1, const S& a2, const S& a3) {
  using std::cos;
  using std::sin;
  Mat3<S> R = axis_rotation(q.k, a3);
  rotate_rows(q.j, S(cos(a2)), S(sin(a2)), R);
  rotate_rows(q.i, S(cos(a1)), S(sin(a1)), R);
  return R;
}

// The same rotation as a quaternion (w, x, y, z) = q_i(a1) q_j(a2) q_k(a3) (Hamilton product).
template <class S>
Eigen::Matrix<S, 4, 1> euler_quaternion(const EulerSequence& q, const S& a1, const S& a2,
                                        const S& a3) {
  using std::cos;
  using std::sin;
  auto axis_quat = [](int m, const S& a) {
    Eigen::Matrix<S, 4, 1> e = Eigen::Matrix<S, 4, 1>::Zero();
    e(0) = cos(0.5 * a);
    e(1 + m) = sin(0.5 * a);
    return e;
  };
  auto mul = [](const Eigen::Matrix<S, 4, 1>& p, const Eigen::Matrix<S, 4, 1>& r) {
    Eigen::Matrix<S, 4, 1> o;
    o(0) = p(0) * r(0) - p(1) * r(1) - p(2) * r(2) - p(3) * r(3);
    o(1) = p(0) * r(1) + p(1) * r(0) + p(2) * r(3) - p(3) * r(2);
    o(2) = p(0) * r(2) - p(1) * r(3) + p(2) * r(0) + p(3) * r(1);
    o(3) = p(0) * r(3) + p(1) * r(2) - p(2) * r(1) + p(3) * r(0);
    return o;
  };
  return mul(mul(axis_quat(q.i, a1), axis_quat(q.j, a2)), axis_quat(q.k, a3));
}

// A(a): w = A(a) a' (header comment; Kane, Likins & Levinson 1983, Sec. 1.16 for 3-2-1).
template <class S>
Mat3<S> euler_rate_matrix(const EulerSequence& q, const S& a2, const S& a3) {
  // Written out (Eigen's products on a dual-number scalar build temporaries): with R_k = R_k(a3),
  // R_j = R_j(a2), column 0 is R_k^T R_j^T e_i (row i of R_j, turned by R_k^T), column 1
  // R_k^T e_j (row j of R_k), column 2 e_k.
  const Mat3<S> Rk = axis_rotation(q.k, a3);
  const Mat3<S> Rj = axis_rotation(q.j, a2);
  Mat3<S> A;
  for (int a = 0; a < 3; ++a) {
    A(a, 0) = Rk(0, a) * Rj(q.i, 0) + Rk(1, a) * Rj(q.i, 1) + Rk(2, a) * Rj(q.i, 2);
    A(a, 1) = Rk(q.j, a);
    A(a, 2) = S(a == q.k ? 1.0 : 0.0);
  }
  return A;
}

// Angles of rotation R in chart q (header comment), a2 in [-pi/2, pi/2].
inline Eigen::Vector3d euler_angles(const EulerSequence& q, const Eigen::Matrix3d& R) {
  const double e = q.eps();
  const double a2 = std::atan2(e * R(q.i, q.k), std::hypot(R(q.i, q.i), R(q.i, q.j)));
  const double a1 = std::atan2(-e * R(q.j, q.k), R(q.k, q.k));
  const double a3 = std::atan2(-e * R(q.i, q.j), R(q.i, q.i));
  return {a1, a2, a3};
}

// |sin a2| of rotation R in chart q: 0 far from the singularity, 1 at gimbal lock.
inline double chart_singularity(const EulerSequence& q, const Eigen::Matrix3d& R) {
  return std::abs(R(q.i, q.k));
}

// The chart whose middle angle is smallest for R (|a2| <= 45 deg, header comment).
inline int best_chart(const Eigen::Matrix3d& R) {
  int best = kDefaultChart;
  for (int c = 0; c < static_cast<int>(kSequences.size()); ++c)
    if (chart_singularity(kSequences[c], R) < chart_singularity(kSequences[best], R)) best = c;
  return best;
}

}  // namespace crossdyn::lagrange
