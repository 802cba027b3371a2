#include "formulations/newton_euler/modal_body.hpp"

#include "core/rotation.hpp"

namespace crossdyn::newton_euler {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using rot::skew;

namespace {
std::size_t at(int i) { return static_cast<std::size_t>(i); }
}  // namespace

ModalInvariants ModalInvariants::from(const FlexBody& flex, const Matrix3d& extra_inertia) {
  ModalInvariants v;
  const int n = flex.modes();
  v.n = n;
  v.Phi_bar = Eigen::Matrix3Xd::Zero(3, n);
  v.Lambda0 = Eigen::Matrix3Xd::Zero(3, n);
  v.M_ee = Eigen::MatrixXd::Zero(n, n);
  v.C.assign(at(n), Matrix3d::Zero());
  v.D.assign(at(n * n), Matrix3d::Zero());
  v.G = Eigen::Matrix3Xd::Zero(3, n * n);
  for (const FlexNode& node : flex.nodes) {
    const double mi = node.mass;
    const Vector3d& p = node.p_BoNi_B;
    v.m += mi;
    v.S0 += mi * p;
    v.J_sum += node.J_Ni_B;
    v.Q0 += mi * p * p.transpose();
    if (n == 0) continue;
    const Eigen::Matrix3Xd& Phi = node.Phi_B;
    v.Phi_bar += mi * Phi;
    v.Lambda0 += mi * skew(p) * Phi;
    v.M_ee += mi * Phi.transpose() * Phi;
    for (int k = 0; k < n; ++k) {
      v.C[at(k)] += mi * Phi.col(k) * p.transpose();
      for (int l = 0; l < n; ++l) {
        v.D[at(k * n + l)] += mi * Phi.col(k) * Phi.col(l).transpose();
        v.G.col(k * n + l) += mi * Phi.col(k).cross(Phi.col(l));
      }
    }
  }
  v.J_sum += extra_inertia;
  v.stiffening = flex.geometric_stiffening && n > 0;
  if (v.stiffening) {
    for (const FlexNode& node : flex.nodes) {
      v.node_m.push_back(node.mass);
      v.node_p.push_back(node.p_BoNi_B);
      v.node_e.push_back(node.e_B);
      v.node_Phi.push_back(node.Phi_B);
      v.node_G.push_back(node.G.size() == 0 ? Eigen::MatrixXd::Zero(n, n) : node.G);
    }
  }
  v.K = flex.K.size() == 0 ? Eigen::MatrixXd::Zero(n, n) : flex.K;
  v.Dmp = flex.D.size() == 0 ? Eigen::MatrixXd::Zero(n, n) : flex.D;
  return v;
}

Matrix3d ModalInvariants::rigid_inertia() const {
  return J_sum + Q0.trace() * Matrix3d::Identity() - Q0;
}

ModalTerms::ModalTerms(int n)
    : Lambda(Eigen::Matrix3Xd::Zero(3, n)),
      B(at(n), Matrix3d::Zero()),
      M(Eigen::MatrixXd::Zero(6 + n, 6 + n)),
      f(Eigen::VectorXd::Zero(6 + n)),
      g(Eigen::VectorXd::Zero(n)),
      Phit(Eigen::Matrix3Xd::Zero(3, n)) {}

Foreshortening foreshortening(const Eigen::MatrixXd& G, const Eigen::Ref<const Eigen::VectorXd>& eta,
                              const Eigen::Ref<const Eigen::VectorXd>& eta_dot) {
  Foreshortening r;
  const Eigen::Index n = eta.size();
  for (Eigen::Index k = 0; k < n; ++k)
    for (Eigen::Index l = 0; l < n; ++l) {
      r.w += eta(k) * G(k, l) * eta(l);
      r.w_dot += eta(k) * G(k, l) * eta_dot(l);
      r.q += eta_dot(k) * G(k, l) * eta_dot(l);
    }
  r.w *= 0.5;
  return r;
}

void modal_first_moments(const ModalInvariants& inv, const Eigen::Ref<const Eigen::VectorXd>& eta,
                         const Eigen::Ref<const Eigen::VectorXd>& eta_dot, Vector3d& S,
                         Vector3d& p_rel) {
  S = inv.S0;
  if (inv.n == 0) {  // no modes: Eigen's 3 x 0 product offsets a null pointer (UBSan)
    p_rel.setZero();
    return;
  }
  S.noalias() += inv.Phi_bar * eta;
  p_rel.noalias() = inv.Phi_bar * eta_dot;
  if (!inv.stiffening) return;
  // The second-order parts: sum m_i e_i w_i and sum m_i e_i d/dt w_i (modal_body.hpp).
  for (std::size_t i = 0; i < inv.node_m.size(); ++i) {
    const Foreshortening fs = foreshortening(inv.node_G[i], eta, eta_dot);
    S += inv.node_m[i] * fs.w * inv.node_e[i];
    p_rel += inv.node_m[i] * fs.w_dot * inv.node_e[i];
  }
}

namespace {

// The geometrically stiffened body's terms by node sums (modal_body.hpp, "Geometric stiffening").
void modal_terms_stiffened(const ModalInvariants& inv, const Matrix3d& R, const Vector3d& w,
                           const Eigen::Ref<const Eigen::VectorXd>& eta,
                           const Eigen::Ref<const Eigen::VectorXd>& eta_dot, ModalTerms& out) {
  const int n = inv.n;
  Eigen::MatrixXd& M = out.M;
  Matrix3d Q = Matrix3d::Zero();  // sum m_i r_i r_i^T
  Vector3d S = Vector3d::Zero(), p_rel = Vector3d::Zero(), h_rel = Vector3d::Zero();
  Vector3d F_tr = Vector3d::Zero(), F_rot = Vector3d::Zero();
  auto Phi_bar = M.block(0, 6, 3, n);   // filled in B components, turned by R below
  auto Mee = M.bottomRightCorner(n, n);
  auto f_modal = out.f.tail(n);
  Phi_bar.setZero();
  Mee.setZero();
  f_modal.setZero();
  out.Lambda.setZero();
  for (std::size_t i = 0; i < inv.node_m.size(); ++i) {
    const double mi = inv.node_m[i];
    const Vector3d& e = inv.node_e[i];
    out.g.noalias() = inv.node_G[i] * eta;                        // G_i eta
    const double wi = 0.5 * eta.dot(out.g);                       // w_i
    out.Phit = inv.node_Phi[i];
    out.Phit.noalias() += e * out.g.transpose();                  // Phi~_i
    double qi = 0;                                                // eta'^T G_i eta'
    for (int k = 0; k < n; ++k)
      for (int l = 0; l < n; ++l) qi += eta_dot(k) * inv.node_G[i](k, l) * eta_dot(l);
    Vector3d r = inv.node_p[i] + wi * e;
    r.noalias() += inv.node_Phi[i] * eta;                         // r_i = p_i + u_i
    Vector3d ud;
    ud.noalias() = out.Phit * eta_dot;                            // u_i'
    const Vector3d c = w.cross(w.cross(r)) + 2.0 * w.cross(ud) + qi * e;  // c_i
    S += mi * r;
    Q.noalias() += mi * r * r.transpose();
    p_rel += mi * ud;
    h_rel += mi * r.cross(ud);
    F_tr += mi * c;
    F_rot += mi * r.cross(c);
    Phi_bar += mi * out.Phit;
    for (int k = 0; k < n; ++k) out.Lambda.col(k) += mi * r.cross(out.Phit.col(k));
    Mee.noalias() += mi * out.Phit.transpose() * out.Phit;
    f_modal.noalias() -= out.Phit.transpose() * (mi * c);
  }
  out.S = S;
  out.I = inv.J_sum + Q.trace() * Matrix3d::Identity() - Q;
  out.p_rel = p_rel;
  out.h_rel = h_rel;
  M.topLeftCorner<3, 3>() = inv.m * Matrix3d::Identity();
  M.block<3, 3>(0, 3).noalias() = -R * skew(out.S);
  M.block<3, 3>(3, 0) = M.block<3, 3>(0, 3).transpose();
  M.block<3, 3>(3, 3) = out.I;
  out.Phit = Phi_bar;                       // B components (scratch), then R Phi~_bar in place
  Phi_bar.noalias() = R * out.Phit;
  M.block(6, 0, n, 3) = Phi_bar.transpose();
  M.block(3, 6, 3, n) = out.Lambda;
  M.block(6, 3, n, 3) = out.Lambda.transpose();
  out.f.head<3>().noalias() = -R * F_tr;
  out.f.segment<3>(3) = -F_rot - w.cross(inv.J_sum * w);
  f_modal.noalias() -= inv.K * eta;
  f_modal.noalias() -= inv.Dmp * eta_dot;
}

}  // namespace

void modal_terms(const ModalInvariants& inv, const Matrix3d& R, const Vector3d& w,
                 const Eigen::Ref<const Eigen::VectorXd>& eta,
                 const Eigen::Ref<const Eigen::VectorXd>& eta_dot, ModalTerms& out) {
  if (inv.stiffening) return modal_terms_stiffened(inv, R, w, eta, eta_dot, out);
  const int n = inv.n;
  // B_k = sum m_i Phi_ik r_i^T and the second moment sum m_i r_i r_i^T (modal_body.hpp).
  Matrix3d Q = inv.Q0;
  Matrix3d P = Matrix3d::Zero();  // sum m_i u_i' r_i^T
  for (int k = 0; k < n; ++k) {
    Matrix3d& Bk = out.B[at(k)];
    Bk = inv.C[at(k)];
    for (int l = 0; l < n; ++l) Bk += eta(l) * inv.D[at(k * n + l)];
    Q += eta(k) * (Bk + inv.C[at(k)].transpose());
    P += eta_dot(k) * Bk;
    // Lambda[:, k] = sum m_i r_i x Phi_ik = vex(B_k - B_k^T).
    out.Lambda.col(k) = Vector3d(Bk(2, 1) - Bk(1, 2), Bk(0, 2) - Bk(2, 0), Bk(1, 0) - Bk(0, 1));
  }
  out.S = inv.S0;
  out.I = inv.J_sum + Q.trace() * Matrix3d::Identity() - Q;
  if (n > 0) {
    out.S.noalias() += inv.Phi_bar * eta;
    out.p_rel.noalias() = inv.Phi_bar * eta_dot;
    out.h_rel.noalias() = out.Lambda * eta_dot;
  } else {  // no modes (a converge model with all dropped): Eigen's product of 3 x 0 blocks
            // offsets a null pointer (UBSan, cli_fuzzer seed converge_nodal)
    out.p_rel.setZero();
    out.h_rel.setZero();
  }

  // Mass matrix (modal_body.hpp): rows/columns [a_N; alpha_B; eta''].
  Eigen::MatrixXd& M = out.M;
  M.topLeftCorner<3, 3>() = inv.m * Matrix3d::Identity();
  M.block<3, 3>(0, 3).noalias() = -R * skew(out.S);
  M.block<3, 3>(3, 0) = M.block<3, 3>(0, 3).transpose();
  M.block<3, 3>(3, 3) = out.I;
  if (n > 0) {
    M.block(0, 6, 3, n).noalias() = R * inv.Phi_bar;
    M.block(6, 0, n, 3) = M.block(0, 6, 3, n).transpose();
    M.block(3, 6, 3, n) = out.Lambda;
    M.block(6, 3, n, 3) = out.Lambda.transpose();
    M.bottomRightCorner(n, n) = inv.M_ee;
  }

  // Quadratic velocity terms, moved to the right-hand side, and the internal modal forces.
  out.f.head<3>().noalias() = -R * (w.cross(w.cross(out.S)) + 2.0 * w.cross(out.p_rel));
  out.f.segment<3>(3) = -w.cross(out.I * w) - 2.0 * (P.trace() * w - P * w);
  const double w2 = w.squaredNorm();
  for (int k = 0; k < n; ++k) {
    const Matrix3d& Bk = out.B[at(k)];
    Vector3d g;  // sum_l G_kl eta'_l = sum m_i Phi_ik x u_i'
    g.noalias() = inv.G.middleCols(k * n, n) * eta_dot;
    out.f(6 + k) = -(w.dot(Bk * w) - w2 * Bk.trace()) + 2.0 * w.dot(g);
  }
  if (n > 0) {
    out.f.tail(n).noalias() -= inv.K * eta;
    out.f.tail(n).noalias() -= inv.Dmp * eta_dot;
  }
}

}  // namespace crossdyn::newton_euler
