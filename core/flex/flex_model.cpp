// The checks every FlexBody passes, whatever built it (core/flex/flex_model.hpp).
#include "core/flex/flex_model.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <set>

#include "core/errors.hpp"

namespace crossdyn::flex {

namespace {

// x in its shortest form that reads back to the same double.
std::string num(double x) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}


Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

bool all_finite(const Eigen::Ref<const Eigen::MatrixXd>& a) { return a.allFinite(); }

}  // namespace

RigidProperties rigid_properties(const FlexBody& f) {
  RigidProperties r;
  for (const FlexNode& n : f.nodes) {
    r.mass += n.mass;
    r.I += n.J_Ni_B +
           n.mass * (n.p_BoNi_B.squaredNorm() * Eigen::Matrix3d::Identity() -
                     n.p_BoNi_B * n.p_BoNi_B.transpose());
  }
  return r;
}

Eigen::MatrixXd rest_mass_matrix(const FlexBody& f) {
  const int n = f.modes();
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(6 + n, 6 + n);
  Eigen::MatrixXd B(3, 6 + n);
  for (const FlexNode& node : f.nodes) {
    B.leftCols<3>().setIdentity();
    B.middleCols<3>(3) = -skew(node.p_BoNi_B);
    B.rightCols(n) = node.Phi_B;
    M.noalias() += node.mass * B.transpose() * B;
    M.block<3, 3>(3, 3) += node.J_Ni_B;
  }
  return M;
}

std::optional<std::string> name_problem(std::string_view name) {
  const auto letter = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); };
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  bool ok = !name.empty() && name.size() <= kMaxNameLength && letter(name.front());
  for (char c : name) ok = ok && (letter(c) || digit(c) || c == '_' || c == '-');
  if (ok) return std::nullopt;
  std::string shown;
  for (char c : name.substr(0, 40)) shown += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (name.size() > 40) shown += "...";
  return "invalid name '" + shown +
         "': use 1 to 64 letters, digits, '_' or '-', starting with a letter";
}

std::optional<std::string> mode_name_problem(std::string_view name) {
  if (auto p = name_problem(name)) return p;
  // A body's own output columns <body>.wx ... <body>.qz (core/output_layout).
  static constexpr std::array<std::string_view, 10> kBodyColumns = {
      "wx", "wy", "wz", "qw", "qx", "qy", "qz", "x", "y", "z"};
  for (std::string_view c : kBodyColumns)
    if (name == c)
      return "mode name '" + std::string(name) +
             "' clashes with the body's output column <body>." + std::string(c);
  constexpr std::string_view kRate = "_rate";
  if (name.size() >= kRate.size() && name.substr(name.size() - kRate.size()) == kRate)
    return "mode name '" + std::string(name) +
           "' ends in '_rate', which would clash with a mode's rate column <body>.<mode>_rate";
  return std::nullopt;
}

std::optional<std::string> inertia_problem(const Eigen::Matrix3d& J) {
  if (!J.allFinite()) return std::string("the inertia has a non-finite entry");
  const double scale = J.cwiseAbs().maxCoeff();
  const double tol = 1e-9 * scale;
  const double asym = (J - J.transpose()).cwiseAbs().maxCoeff();
  if (asym > tol) return "the inertia is not symmetric (entries differ by " + num(asym) + ")";
  if (scale == 0) return std::nullopt;
  const Eigen::Vector3d l = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(J).eigenvalues();
  if (l(0) < -tol)
    return "the inertia is not positive semi-definite (principal moments " + num(l(0)) + ", " +
           num(l(1)) + ", " + num(l(2)) + ")";
  if (l(0) + l(1) < l(2) - tol)
    return "the inertia is not physically realisable: principal moments " + num(l(0)) + ", " +
           num(l(1)) + ", " + num(l(2)) + " break the triangle inequality I1 + I2 >= I3";
  return std::nullopt;
}

std::optional<std::string> modal_matrix_problem(const Eigen::MatrixXd& A, const FlexBody& f,
                                                std::string_view what) {
  const int n = f.modes();
  const std::string W(what);
  if (A.rows() != n || A.cols() != n)
    return W + " is " + std::to_string(A.rows()) + " x " + std::to_string(A.cols()) + " but the body has " +
           std::to_string(n) + " modes";
  const auto mode = [&](Eigen::Index i) { return f.mode_names[static_cast<std::size_t>(i)]; };
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < n; ++i)
      if (!std::isfinite(A(i, j)))
        return W + "(" + mode(i) + ", " + mode(j) + ") is not finite";
  if (n == 0) return std::nullopt;
  const double scale = A.cwiseAbs().maxCoeff();
  Eigen::Index bi = 0, bj = 0;
  const double asym = (A - A.transpose()).cwiseAbs().maxCoeff(&bi, &bj);
  if (asym > 1e-9 * scale)
    return W + " is not symmetric: " + W + "(" + mode(bi) + ", " + mode(bj) + ") = " +
           num(A(bi, bj)) + " but " + W + "(" + mode(bj) + ", " + mode(bi) + ") = " + num(A(bj, bi));
  if (scale == 0) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A);
  const Eigen::VectorXd& l = es.eigenvalues();
  const double largest = l.cwiseAbs().maxCoeff();
  if (l(0) < -1e-9 * largest) {
    Eigen::Index k = 0;
    es.eigenvectors().col(0).cwiseAbs().maxCoeff(&k);
    return W + " is not positive semi-definite: eigenvalue " + num(l(0)) + " (the largest is " +
           num(l(n - 1)) + "), its eigenvector mostly along mode '" + mode(k) + "'";
  }
  return std::nullopt;
}

void validate_flex(const FlexBody& f, const std::string& context) {
  const auto fail = [&](const std::string& what) { throw InputError(context + ": " + what); };
  const int n = f.modes();
  if (n > kMaxModes)
    fail(std::to_string(n) + " modes: at most " + std::to_string(kMaxModes) + " are accepted");
  std::set<std::string_view> seen;
  for (const std::string& m : f.mode_names) {
    if (auto p = mode_name_problem(m)) fail(*p);
    if (!seen.insert(m).second) fail("duplicate mode name '" + m + "'");
  }
  // Geometric stiffening foreshortens the modes' deformation (e 1/2 eta^T G eta): with no modes
  // there is nothing to foreshorten, and the engines' stiffening terms are sized by the modes
  // (an empty G is not a model they accept: a segfault in the Kane engine). A body without modes
  // is the rigid body (docs/flexible-bodies.md), stated without stiffening; the beam generator
  // refuses it at its key (beam_spec_problems), converge's truncation switches it off.
  if (f.geometric_stiffening && n == 0)
    fail("geometric stiffening needs modes: the body has none, so there is no deformation to "
         "foreshorten (switch geometric stiffening off: a body without modes is rigid)");
  if (f.nodes.empty()) fail("the body has no nodes: at least one node must carry its mass");
  if (f.nodes.size() > kMaxNodes)
    fail(std::to_string(f.nodes.size()) + " nodes: at most " + std::to_string(kMaxNodes) +
         " are accepted");

  seen.clear();
  double extent = 0;
  for (const FlexNode& node : f.nodes) {
    if (auto p = name_problem(node.name)) fail("node: " + *p);
    if (!seen.insert(node.name).second) fail("duplicate node name '" + node.name + "'");
    const std::string at = "node '" + node.name + "': ";
    if (!std::isfinite(node.mass) || node.mass < 0)
      fail(at + "mass " + num(node.mass) + " kg: a node's mass must be finite and >= 0");
    if (!node.p_BoNi_B.allFinite()) fail(at + "position is not finite");
    if (auto p = inertia_problem(node.J_Ni_B)) fail(at + "J: " + *p);
    if (node.Phi_B.rows() != 3 || node.Phi_B.cols() != n || node.Psi_B.rows() != 3 ||
        node.Psi_B.cols() != n)
      fail(at + "mode shapes are " + std::to_string(node.Phi_B.rows()) + " x " +
           std::to_string(node.Phi_B.cols()) + " and slopes " + std::to_string(node.Psi_B.rows()) +
           " x " + std::to_string(node.Psi_B.cols()) + ", expected 3 x " + std::to_string(n) +
           " (one column per mode)");
    for (int k = 0; k < n; ++k) {
      if (!all_finite(node.Phi_B.col(k)))
        fail(at + "mode '" + f.mode_names[static_cast<std::size_t>(k)] + "': shape is not finite");
      if (!all_finite(node.Psi_B.col(k)))
        fail(at + "mode '" + f.mode_names[static_cast<std::size_t>(k)] + "': slope is not finite");
    }
    if (f.geometric_stiffening) {
      if (node.G.rows() != n || node.G.cols() != n)
        fail(at + "geometric stiffening: G is " + std::to_string(node.G.rows()) + " x " +
             std::to_string(node.G.cols()) + ", expected " + std::to_string(n) + " x " +
             std::to_string(n));
      if (!node.G.allFinite() || !node.e_B.allFinite())
        fail(at + "geometric stiffening: G or e is not finite");
      if (std::abs(node.e_B.norm() - 1) > 1e-12)
        fail(at + "geometric stiffening: e is not a unit vector");
      if ((node.G - node.G.transpose()).cwiseAbs().maxCoeff() >
          1e-12 * std::max(1.0, node.G.cwiseAbs().maxCoeff()))
        fail(at + "geometric stiffening: G is not symmetric");
    } else if (node.G.size() != 0) {
      fail(at + "G is set but the body has no geometric stiffening");
    }
    extent = std::max(extent, node.p_BoNi_B.norm());
  }

  const RigidProperties rigid = rigid_properties(f);
  if (!(rigid.mass > 0)) fail("the nodes' total mass is zero: at least one node needs mass");
  Eigen::Vector3d first_moment = Eigen::Vector3d::Zero();
  for (const FlexNode& node : f.nodes) first_moment += node.mass * node.p_BoNi_B;
  if (first_moment.norm() > 1e-9 * rigid.mass * extent) {
    const Eigen::Vector3d c = first_moment / rigid.mass;
    fail("the nodes' centre of mass is at [" + num(c.x()) + ", " + num(c.y()) + ", " + num(c.z()) +
         "] m, not at the body origin (node positions are from the undeformed CM: sum m_i p_i = 0)");
  }
  {
    const Eigen::Vector3d l =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(rigid.I).eigenvalues();
    if (!(l(0) > 1e-9 * l(2)))
      fail("the rigid inertia (node sum) is singular, principal moments " + num(l(0)) + ", " +
           num(l(1)) + ", " + num(l(2)) +
           " kg m^2: the mass lies on a line; give the nodes a rotational inertia J");
  }

  // Modes against rigid motion: the rest mass matrix scaled to unit diagonal.
  if (n > 0) {
    const Eigen::MatrixXd M = rest_mass_matrix(f);
    for (int k = 0; k < n; ++k)
      if (!(M(6 + k, 6 + k) > 0))
        fail("mode '" + f.mode_names[static_cast<std::size_t>(k)] +
             "' moves no mass (its shape is zero at every node with mass)");
    const Eigen::VectorXd s = M.diagonal().cwiseSqrt().cwiseInverse();
    const Eigen::MatrixXd S = s.asDiagonal() * M * s.asDiagonal();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
    if (es.eigenvalues()(0) < 1e-10) {
      Eigen::Index k = 0;
      es.eigenvectors().col(0).tail(n).cwiseAbs().maxCoeff(&k);
      fail("mode '" + f.mode_names[static_cast<std::size_t>(k)] +
           "' is (nearly) a rigid-body motion of the body or a combination of other modes (the "
           "mass matrix of rigid motion and modes, scaled to unit diagonal, has smallest "
           "eigenvalue " + num(es.eigenvalues()(0)) + "): remove rigid-body modes from the data");
    }
  }
  if (auto p = modal_matrix_problem(f.K, f, "K")) fail(*p);
  if (auto p = modal_matrix_problem(f.D, f, "D")) fail(*p);
}

}  // namespace crossdyn::flex
