#include "formulations/newton_euler/modal_body.hpp"

#include "core/rotation.hpp"
#include "formulations/newton_euler/scalar.hpp"

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

template <class S>
ModalTermsT<S>::ModalTermsT(int n)
    : Lambda(M3X::Zero(3, n)),
      B(at(n), M3::Zero()),
      M(MX::Zero(6 + n, 6 + n)),
      f(VX::Zero(6 + n)),
      g(VX::Zero(n)),
      Phit(M3X::Zero(3, n)) {}

template struct ModalTermsT<double>;
template struct ModalTermsT<Cx>;

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
template <class T>
void modal_terms_stiffened(const ModalInvariants& inv, const Mat3<T>& R, const Vec3<T>& w,
                           const Eigen::Ref<const Eigen::Matrix<T, Eigen::Dynamic, 1>>& eta,
                           const Eigen::Ref<const Eigen::Matrix<T, Eigen::Dynamic, 1>>& eta_dot,
                           ModalTermsT<T>& out) {
  using V3 = Vec3<T>;
  using M3 = Mat3<T>;
  const int n = inv.n;
  auto& M = out.M;
  M3 Q = M3::Zero();  // sum m_i r_i r_i^T
  V3 S = V3::Zero(), p_rel = V3::Zero(), h_rel = V3::Zero();
  V3 F_tr = V3::Zero(), F_rot = V3::Zero();
  auto Phi_bar = M.block(0, 6, 3, n);   // filled in B components, turned by R below
  auto Mee = M.bottomRightCorner(n, n);
  auto f_modal = out.f.tail(n);
  Phi_bar.setZero();
  Mee.setZero();
  f_modal.setZero();
  out.Lambda.setZero();
  for (std::size_t i = 0; i < inv.node_m.size(); ++i) {
    const double mi = inv.node_m[i];
    const V3 e = inv.node_e[i].template cast<T>();
    out.g.noalias() = inv.node_G[i] * eta;                        // G_i eta
    const T wi = 0.5 * tdot<T>(eta, out.g);                       // w_i
    out.Phit = inv.node_Phi[i].template cast<T>();
    out.Phit.noalias() += e * out.g.transpose();                  // Phi~_i
    T qi = 0;                                                     // eta'^T G_i eta'
    for (int k = 0; k < n; ++k)
      for (int l = 0; l < n; ++l) qi += eta_dot(k) * inv.node_G[i](k, l) * eta_dot(l);
    V3 r = inv.node_p[i].template cast<T>() + wi * e;
    r.noalias() += inv.node_Phi[i] * eta;                         // r_i = p_i + u_i
    V3 ud;
    ud.noalias() = out.Phit * eta_dot;                            // u_i'
    const V3 c = tcross<T>(w, tcross<T>(w, r)) + 2.0 * tcross<T>(w, ud) + qi * e;  // c_i
    S += mi * r;
    Q.noalias() += mi * r * r.transpose();
    p_rel += mi * ud;
    h_rel += mi * tcross<T>(r, ud);
    F_tr += mi * c;
    F_rot += mi * tcross<T>(r, c);
    Phi_bar += mi * out.Phit;
    for (int k = 0; k < n; ++k) out.Lambda.col(k) += mi * tcross<T>(r, out.Phit.col(k));
    Mee.noalias() += mi * out.Phit.transpose() * out.Phit;
    f_modal.noalias() -= out.Phit.transpose() * (mi * c);
  }
  out.S = S;
  out.I = inv.J_sum.template cast<T>() + Q.trace() * M3::Identity() - Q;
  out.p_rel = p_rel;
  out.h_rel = h_rel;
  M.template topLeftCorner<3, 3>() = (inv.m * Matrix3d::Identity()).template cast<T>();
  M.template block<3, 3>(0, 3).noalias() = -R * tskew<T>(out.S);
  M.template block<3, 3>(3, 0) = M.template block<3, 3>(0, 3).transpose();
  M.template block<3, 3>(3, 3) = out.I;
  out.Phit = Phi_bar;                       // B components (scratch), then R Phi~_bar in place
  Phi_bar.noalias() = R * out.Phit;
  M.block(6, 0, n, 3) = Phi_bar.transpose();
  M.block(3, 6, 3, n) = out.Lambda;
  M.block(6, 3, n, 3) = out.Lambda.transpose();
  out.f.template head<3>().noalias() = -R * F_tr;
  out.f.template segment<3>(3) = -F_rot - tcross<T>(w, V3(inv.J_sum * w));
  f_modal.noalias() -= inv.K * eta;
  f_modal.noalias() -= inv.Dmp * eta_dot;
}

}  // namespace

template <class T>
void modal_terms_t(const ModalInvariants& inv, const Mat3<T>& R, const Vec3<T>& w,
                   const Eigen::Ref<const Eigen::Matrix<T, Eigen::Dynamic, 1>>& eta,
                   const Eigen::Ref<const Eigen::Matrix<T, Eigen::Dynamic, 1>>& eta_dot,
                   ModalTermsT<T>& out) {
  using V3 = Vec3<T>;
  using M3 = Mat3<T>;
  if (inv.stiffening) return modal_terms_stiffened<T>(inv, R, w, eta, eta_dot, out);
  const int n = inv.n;
  // B_k = sum m_i Phi_ik r_i^T and the second moment sum m_i r_i r_i^T (modal_body.hpp).
  M3 Q = inv.Q0.template cast<T>();
  M3 P = M3::Zero();  // sum m_i u_i' r_i^T
  for (int k = 0; k < n; ++k) {
    M3& Bk = out.B[at(k)];
    Bk = inv.C[at(k)].template cast<T>();
    for (int l = 0; l < n; ++l) Bk += eta(l) * inv.D[at(k * n + l)];
    Q += eta(k) * (Bk + inv.C[at(k)].transpose());
    P += eta_dot(k) * Bk;
    // Lambda[:, k] = sum m_i r_i x Phi_ik = vex(B_k - B_k^T).
    out.Lambda.col(k) = V3(Bk(2, 1) - Bk(1, 2), Bk(0, 2) - Bk(2, 0), Bk(1, 0) - Bk(0, 1));
  }
  out.S = inv.S0.template cast<T>();
  out.I = inv.J_sum.template cast<T>() + Q.trace() * M3::Identity() - Q;
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
  auto& M = out.M;
  M.template topLeftCorner<3, 3>() = (inv.m * Matrix3d::Identity()).template cast<T>();
  M.template block<3, 3>(0, 3).noalias() = -R * tskew<T>(out.S);
  M.template block<3, 3>(3, 0) = M.template block<3, 3>(0, 3).transpose();
  M.template block<3, 3>(3, 3) = out.I;
  if (n > 0) {
    M.block(0, 6, 3, n).noalias() = R * inv.Phi_bar;
    M.block(6, 0, n, 3) = M.block(0, 6, 3, n).transpose();
    M.block(3, 6, 3, n) = out.Lambda;
    M.block(6, 3, n, 3) = out.Lambda.transpose();
    M.bottomRightCorner(n, n) = inv.M_ee.template cast<T>();
  }

  // Quadratic velocity terms, moved to the right-hand side, and the internal modal forces.
  out.f.template head<3>().noalias() =
      -R * (tcross<T>(w, tcross<T>(w, out.S)) + 2.0 * tcross<T>(w, out.p_rel));
  out.f.template segment<3>(3) = -tcross<T>(w, V3(out.I * w)) - 2.0 * (P.trace() * w - P * w);
  const T w2 = tsquared_norm<T>(w);
  for (int k = 0; k < n; ++k) {
    const M3& Bk = out.B[at(k)];
    V3 g;  // sum_l G_kl eta'_l = sum m_i Phi_ik x u_i'
    g.noalias() = inv.G.middleCols(k * n, n) * eta_dot;
    out.f(6 + k) = -(tdot<T>(w, V3(Bk * w)) - w2 * Bk.trace()) + 2.0 * tdot<T>(w, g);
  }
  if (n > 0) {
    out.f.tail(n).noalias() -= inv.K * eta;
    out.f.tail(n).noalias() -= inv.Dmp * eta_dot;
  }
}

template void modal_terms_t(const ModalInvariants&, const Mat3<double>&, const Vec3<double>&,
                            const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 1>>&,
                            const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 1>>&,
                            ModalTermsT<double>&);
template void modal_terms_t(const ModalInvariants&, const Mat3<Cx>&, const Vec3<Cx>&,
                            const Eigen::Ref<const Eigen::Matrix<Cx, Eigen::Dynamic, 1>>&,
                            const Eigen::Ref<const Eigen::Matrix<Cx, Eigen::Dynamic, 1>>&,
                            ModalTermsT<Cx>&);

void modal_terms(const ModalInvariants& inv, const Matrix3d& R, const Vector3d& w,
                 const Eigen::Ref<const Eigen::VectorXd>& eta,
                 const Eigen::Ref<const Eigen::VectorXd>& eta_dot, ModalTerms& out) {
  modal_terms_t<double>(inv, R, w, eta, eta_dot, out);
}

}  // namespace crossdyn::newton_euler
