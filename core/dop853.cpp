// DOP853 (see dop853.hpp). Stages are numbered 0..15 here (the book's k_1..k_16):
//   0..11  the stages of the step, 11 of them new (stage 0 is the last step's f at its end, FSAL);
//   12     f(t + h, x_new), the next step's stage 0 (kA row 12 holds the weights b of x_new);
//   13..15 the continuous extension's stages (Hairer et al. I, Sec. II.6: a continuous method adds
//          stages so that the interpolant keeps a high order).
#include "core/dop853.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace crossdyn::integrate_detail {

namespace {

constexpr int kStages = 12;    // per step
constexpr int kExtended = 16;  // with the continuous extension's stages

// Nodes c_i (dop853.f: C2..C16; c_13 = 1 is the FSAL point, c_14..c_16 the extension's).
constexpr double kC[kExtended] = {
    0.0,
    0.526001519587677318785587544488e-01,
    0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510,
    0.281649658092772603273242802490,
    0.333333333333333333333333333333,
    0.25,
    0.307692307692307692307692307692,
    0.651282051282051282051282051282,
    0.6,
    0.857142857142857142857142857142,
    1.0,
    1.0,
    0.1,
    0.2,
    0.777777777777777777777777777778};

// Coupling coefficients a_ij (dop853.f: A21..A1615), row i = stage i. Row 12 is the weights b_j of
// the order-8 solution (dop853.f: B1..B12), so that stage 12 is evaluated at x_new itself.
constexpr double kA[kExtended][kExtended] = {
    {},
    {5.26001519587677318785587544488e-2},
    {1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2},
    {2.95875854768068491816892993775e-2, 0, 8.87627564304205475450678981324e-2},
    {2.41365134159266685502369798665e-1, 0, -8.84549479328286085344864962717e-1,
     9.24834003261792003115737966543e-1},
    {3.7037037037037037037037037037e-2, 0, 0, 1.70828608729473871279604482173e-1,
     1.25467687566822425016691814123e-1},
    {3.7109375e-2, 0, 0, 1.70252211019544039314978060272e-1, 6.02165389804559606850219397283e-2,
     -1.7578125e-2},
    {3.70920001185047927108779319836e-2, 0, 0, 1.70383925712239993810214054705e-1,
     1.07262030446373284651809199168e-1, -1.53194377486244017527936158236e-2,
     8.27378916381402288758473766002e-3},
    {6.24110958716075717114429577812e-1, 0, 0, -3.36089262944694129406857109825,
     -8.68219346841726006818189891453e-1, 2.75920996994467083049415600797e1,
     2.01540675504778934086186788979e1, -4.34898841810699588477366255144e1},
    {4.77662536438264365890433908527e-1, 0, 0, -2.48811461997166764192642586468,
     -5.90290826836842996371446475743e-1, 2.12300514481811942347288949897e1,
     1.52792336328824235832596922938e1, -3.32882109689848629194453265587e1,
     -2.03312017085086261358222928593e-2},
    {-9.3714243008598732571704021658e-1, 0, 0, 5.18637242884406370830023853209,
     1.09143734899672957818500254654, -8.14978701074692612513997267357,
     -1.85200656599969598641566180701e1, 2.27394870993505042818970056734e1,
     2.49360555267965238987089396762, -3.0467644718982195003823669022},
    {2.27331014751653820792359768449, 0, 0, -1.05344954667372501984066689879e1,
     -2.00087205822486249909675718444, -1.79589318631187989172765950534e1,
     2.79488845294199600508499808837e1, -2.85899827713502369474065508674,
     -8.87285693353062954433549289258, 1.23605671757943030647266201528e1,
     6.43392746015763530355970484046e-1},
    {5.42937341165687622380535766363e-2, 0, 0, 0, 0, 4.45031289275240888144113950566,
     1.89151789931450038304281599044, -5.8012039600105847814672114227,
     3.1116436695781989440891606237e-1, -1.52160949662516078556178806805e-1,
     2.01365400804030348374776537501e-1, 4.47106157277725905176885569043e-2},
    {5.61675022830479523392909219681e-2, 0, 0, 0, 0, 0, 2.53500210216624811088794765333e-1,
     -2.46239037470802489917441475441e-1, -1.24191423263816360469010140626e-1,
     1.5329179827876569731206322685e-1, 8.20105229563468988491666602057e-3,
     7.56789766054569976138603589584e-3, -8.298e-3},
    {3.18346481635021405060768473261e-2, 0, 0, 0, 0, 2.83009096723667755288322961402e-2,
     5.35419883074385676223797384372e-2, -5.49237485713909884646569340306e-2, 0, 0,
     -1.08347328697249322858509316994e-4, 3.82571090835658412954920192323e-4,
     -3.40465008687404560802977114492e-4, 1.41312443674632500278074618366e-1},
    {-4.28896301583791923408573538692e-1, 0, 0, 0, 0, -4.69762141536116384314449447206,
     7.68342119606259904184240953878, 4.06898981839711007970213554331,
     3.56727187455281109270669543021e-1, 0, 0, 0, -1.39902416515901462129418009734e-3,
     2.9475147891527723389556272149, -9.15095847217987001081870187138}};

// The order-5 error estimator: err5 = h sum_j e5_j k_j (dop853.f: ER1..ER12).
constexpr double kE5[kStages] = {
    0.1312004499419488073250102996e-1, 0, 0, 0, 0, -0.1225156446376204440720569753e1,
    -0.4957589496572501915214079952, 0.1664377182454986536961530415e1,
    -0.3503288487499736816886487290, 0.3341791187130174790297318841,
    0.8192320648511571246570742613e-1, -0.2235530786388629525884427845e-1};

// The order-3 estimator: err3 = h sum_j (b_j - bhh_j) k_j, bhh only at stages 0, 8, 11
// (dop853.f: BHH1..BHH3).
constexpr double kBhh0 = 0.244094488188976377952755905512;
constexpr double kBhh8 = 0.733846688281611857341361741547;
constexpr double kBhh11 = 0.220588235294117647058823529412e-1;

// The continuous extension's coefficients d_4j..d_7j (dop853.f: D41..D716), stages 0..15.
constexpr double kD[4][kExtended] = {
    {-0.84289382761090128651353491142e1, 0, 0, 0, 0, 0.56671495351937776962531783590,
     -0.30689499459498916912797304727e1, 0.23846676565120698287728149680e1,
     0.21170345824450282767155149946e1, -0.87139158377797299206789907490,
     0.22404374302607882758541771650e1, 0.63157877876946881815570249290,
     -0.88990336451333310820698117400e-1, 0.18148505520854727256656404962e2,
     -0.91946323924783554000451984436e1, -0.44360363875948939664310572000e1},
    {0.10427508642579134603413151009e2, 0, 0, 0, 0, 0.24228349177525818288430175319e3,
     0.16520045171727028198505394887e3, -0.37454675472269020279518312152e3,
     -0.22113666853125306036270938578e2, 0.77334326684722638389603898808e1,
     -0.30674084731089398182061213626e2, -0.93321305264302278729567221706e1,
     0.15697238121770843886131091075e2, -0.31139403219565177677282850411e2,
     -0.93529243588444783865713862664e1, 0.35816841486394083752465898540e2},
    {0.19985053242002433820987653617e2, 0, 0, 0, 0, -0.38703730874935176555105901742e3,
     -0.18917813819516756882830838328e3, 0.52780815920542364900561016686e3,
     -0.11573902539959630126141871134e2, 0.68812326946963000169666922661e1,
     -0.10006050966910838403183860980e1, 0.77771377980534432092869265740,
     -0.27782057523535084065932004339e1, -0.60196695231264120758267380846e2,
     0.84320405506677161018159903784e2, 0.11992291136182789328035130030e2},
    {-0.25693933462703749003312586129e2, 0, 0, 0, 0, -0.15418974869023643374053993627e3,
     -0.23152937917604549567536039109e3, 0.35763911791061412378285349910e3,
     0.93405324183624310003907691704e2, -0.37458323136451633156875139351e2,
     0.10409964950896230045147246184e3, 0.29840293426660503123344363579e2,
     -0.43533456590011143754432175058e2, 0.96324553959188282948394950600e2,
     -0.39177261675615439165231486172e2, -0.14972683625798562581422125276e3}};

// Step-size control of dop853.f (Hairer et al. I, Sec. II.4, Eq. (4.13) with the exponent 1/8 of
// an order-8 pair), stabilised as the codes' parameter BETA allows ("Lund stabilisation", a PI
// controller: Gustafsson, ACM TOMS 17(4), 1991): h_new = h * min(kGrow, max(kShrink,
// kSafety * err^-(1/8 - 0.2 kBeta) * err_old^kBeta)); no growth right after a rejection.
// kBeta = 0.04 (dopri5.f's default; dop853.f's is 0): measured with kane on spear1_case1
// (`crossdyn run scenarios/spear1_case1.yaml --engine kane --integrator dop853 --stats`), right-hand
// sides at tolerance 1e-8 / 5e-11 / 1e-12: beta 0: 267 / 461 / 659 (3, 6, 6 rejected steps);
// 0.04: 260 / 435 / 620 (1, 2, 0 rejected); 0.08: 308 / 533 / 830 (too cautious).
constexpr double kSafety = 0.9;
constexpr double kShrink = 0.333;
constexpr double kGrow = 6.0;
constexpr double kBeta = 0.04;

}  // namespace

void Dop853::initialize(const State& x, double t, double dt, const State* f_x) {
  const std::size_t n = x.size();
  x_ = x;
  t_ = t;
  dt_ = dt;
  have_k1_ = false;
  fsal_pending_ = false;
  dense_ready_ = false;
  last_rejected_ = false;
  facold_ = 1e-4;
  if (k_.size() != kExtended || k_[0].size() != n) {
    k_.assign(kExtended, State(n));
    r_.assign(7, State(n));
    x_old_.assign(n, 0.0);
    x_trial_.assign(n, 0.0);
    x_stage_.assign(n, 0.0);
    est5_.assign(n, 0.0);
    est3_.assign(n, 0.0);
  }
  if (f_x != nullptr && f_x->size() == n) {
    k_[0] = *f_x;
    have_k1_ = true;
  }
}

// out = base + sum_j c_j k_j over the stages with c_j != 0 (base null: 0), four stages per pass
// over the vectors so that out is loaded and stored once per four terms.
// On x86-64 with GCC it is compiled twice, for the baseline and for x86-64-v3 (AVX2: four doubles
// per instruction), and the loader picks the one the processor runs (GCC function multiversioning,
// as core/csv_format.cpp's row writer). Both give the same bits: the sums are element by element
// in the same order, and this file is compiled with -ffp-contract=off (core/CMakeLists.txt), so no
// multiply-add is fused (with it GCC fused them in the AVX2 clone: 1.5e-13 relative differences
// on spear1_case1; without, the CSV is byte-identical to the baseline clone's).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
[[gnu::target_clones("arch=x86-64-v3", "default")]]
#endif
void Dop853::sum_stages(const double* c, int stages, const double* base, double* out) const {
  const std::size_t n = x_.size();
  double coef[kExtended];
  const double* vec[kExtended];
  int m = 0;
  for (int j = 0; j < stages; ++j)
    if (c[j] != 0.0) {
      coef[m] = c[j];
      vec[m++] = k_[static_cast<std::size_t>(j)].data();
    }
  double* __restrict o = out;
  if (base != nullptr) {
    const double* __restrict b = base;
    for (std::size_t i = 0; i < n; ++i) o[i] = b[i];
  } else {
    std::fill(o, o + n, 0.0);
  }
  int j = 0;
  for (; j + 4 <= m; j += 4) {
    const double c0 = coef[j], c1 = coef[j + 1], c2 = coef[j + 2], c3 = coef[j + 3];
    const double* __restrict k0 = vec[j];
    const double* __restrict k1 = vec[j + 1];
    const double* __restrict k2 = vec[j + 2];
    const double* __restrict k3 = vec[j + 3];
    for (std::size_t i = 0; i < n; ++i) o[i] += (c0 * k0[i] + c1 * k1[i]) + (c2 * k2[i] + c3 * k3[i]);
  }
  for (; j + 2 <= m; j += 2) {
    const double c0 = coef[j], c1 = coef[j + 1];
    const double* __restrict k0 = vec[j];
    const double* __restrict k1 = vec[j + 1];
    for (std::size_t i = 0; i < n; ++i) o[i] += c0 * k0[i] + c1 * k1[i];
  }
  for (; j < m; ++j) {
    const double c0 = coef[j];
    const double* __restrict k0 = vec[j];
    for (std::size_t i = 0; i < n; ++i) o[i] += c0 * k0[i];
  }
}

void Dop853::combine(const double* a, int stages, double h, const State& x, State& x_out) const {
  double ha[kExtended];
  for (int j = 0; j < stages; ++j) ha[j] = h * a[j];
  sum_stages(ha, stages, x.data(), x_out.data());
}

std::pair<double, double> Dop853::step(Rhs f) {
  f_ = f;
  const std::size_t n = x_.size();
  if (fsal_pending_) {
    // Stage 0 is f at the end of the last step, kept in stage 12 until now for its extension.
    std::swap(k_[0], k_[kStages]);
    fsal_pending_ = false;
    dense_ready_ = false;
    have_k1_ = true;
  } else if (!have_k1_) {
    f(x_, k_[0], t_);  // throws: nothing changed
    have_k1_ = true;
  }
  for (;;) {
    const double h = dt_;
    // Stages 1..11 (Hairer et al. I, Eq. (II.1.8)), then the order-8 solution (row 12 = b).
    for (int i = 1; i < kStages; ++i) {
      combine(kA[i], i, h, x_, x_stage_);
      f(x_stage_, k_[static_cast<std::size_t>(i)], t_ + kC[i] * h);
    }
    combine(kA[kStages], kStages, h, x_, x_trial_);

    // Error estimate of dop853.f (Hairer et al. I, Sec. II.10, "an 8th order method with
    // stepsize control"): two estimators of orders 5 and 3 combined as
    //   err = |h| e5^2 / sqrt(n (e5^2 + 0.01 e3^2)),  e_p^2 = sum_i (est_p,i / sk_i)^2,
    //   sk_i = atol + rtol max(|x_i|, |x_new,i|).
    // est5 = sum_j e5_j k_j, est3 = sum_j (b_j - bhh_j) k_j (both without the factor h).
    double b_minus_bhh[kStages];
    for (int j = 0; j < kStages; ++j) b_minus_bhh[j] = kA[kStages][j];
    b_minus_bhh[0] -= kBhh0;
    b_minus_bhh[8] -= kBhh8;
    b_minus_bhh[11] -= kBhh11;
    sum_stages(kE5, kStages, nullptr, est5_.data());
    sum_stages(b_minus_bhh, kStages, nullptr, est3_.data());
    double e5 = 0, e3 = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double sk = atol_ + rtol_ * std::max(std::abs(x_[i]), std::abs(x_trial_[i]));
      const double q5 = est5_[i] / sk, q3 = est3_[i] / sk;
      e5 += q5 * q5;
      e3 += q3 * q3;
    }
    double denominator = e5 + 0.01 * e3;
    if (!(denominator > 0)) denominator = 1;
    const double err = std::abs(h) * e5 / std::sqrt(static_cast<double>(n) * denominator);

    // h_new = h * safety * err^-(1/8 - 0.2 beta) * err_old^beta (err_old: the last accepted step's).
    // A non-finite estimate (finite derivatives can still overflow it) gives kShrink, like a large
    // one: std::max(kShrink, NaN) is kShrink.
    const double factor =
        std::min(kGrow, std::max(kShrink, kSafety * std::pow(err, -(1.0 / 8.0 - 0.2 * kBeta)) *
                                               std::pow(facold_, kBeta)));
    if (!(err <= 1.0)) {  // rejected (err > 1 or not finite): retried shorter
      dt_ = h * std::min(1.0, factor);
      last_rejected_ = true;
      if (on_reject_) on_reject_(t_, dt_);
      continue;
    }
    // Accepted: the FSAL stage at the new point (it may throw: then the step is not taken).
    f(x_trial_, k_[kStages], t_ + h);
    facold_ = std::max(err, 1e-4);
    std::swap(x_old_, x_);
    std::swap(x_, x_trial_);
    t_old_ = t_;
    h_old_ = h;
    t_ = t_old_ + h;
    dt_ = last_rejected_ ? std::min(h, h * factor) : h * factor;
    last_rejected_ = false;
    dense_ready_ = false;
    fsal_pending_ = true;  // the next step's stage 0 is stage 12 (swapped in by the next step)
    return {t_old_, t_};
  }
}

void Dop853::prepare_dense() {
  const double h = h_old_;
  // The extension's stages 13..15 at t_old + c_i h (they use stage 12, f at the new point).
  for (int i = kStages + 1; i < kExtended; ++i) {
    combine(kA[i], i, h, x_old_, x_stage_);
    f_(x_stage_, k_[static_cast<std::size_t>(i)], t_old_ + kC[i] * h);
  }
  // Its coefficient vectors (dop853.f, the CONT array; Hairer et al. I, Sec. II.6):
  //   r0 = x_new - x_old, r1 = h f_old - r0, r2 = 2 r0 - h (f_new + f_old),
  //   r3..r6 = h sum_j d_(4..7)j k_j.
  const std::size_t n = x_.size();
  const State& f_old = k_[0];
  const State& f_new = k_[kStages];
  for (std::size_t i = 0; i < n; ++i) {
    const double delta = x_[i] - x_old_[i];
    r_[0][i] = delta;
    r_[1][i] = h * f_old[i] - delta;
    r_[2][i] = 2.0 * delta - h * (f_new[i] + f_old[i]);
  }
  for (int m = 0; m < 4; ++m) {
    double hd[kExtended];
    for (int j = 0; j < kExtended; ++j) hd[j] = h * kD[m][j];
    sum_stages(hd, kExtended, nullptr, r_[static_cast<std::size_t>(m + 3)].data());
  }
  dense_ready_ = true;
}

void Dop853::calc_state(double t, State& x) {
  if (!fsal_pending_) throw std::logic_error("Dop853::calc_state: no step taken since the start");
  if (!dense_ready_) prepare_dense();
  // x(t_old + s h) = x_old + s (r0 + s1 (r1 + s (r2 + s1 (r3 + s (r4 + s1 (r5 + s r6)))))),
  // s1 = 1 - s (dop853.f, CONTD8).
  const double s = (t - t_old_) / h_old_, s1 = 1.0 - s;
  const std::size_t n = x_.size();
  x.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double inner =
        r_[3][i] + s * (r_[4][i] + s1 * (r_[5][i] + s * r_[6][i]));
    x[i] = x_old_[i] + s * (r_[0][i] + s1 * (r_[1][i] + s * (r_[2][i] + s1 * inner)));
  }
}

}  // namespace crossdyn::integrate_detail
