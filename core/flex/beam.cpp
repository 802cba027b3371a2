// The beam generator (core/flex/beam.hpp): closed-form Euler-Bernoulli modes sampled at composite
// Gauss-Legendre mass points, at massless slice-centre stations and at the ends.
#include "core/flex/beam.hpp"

#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/special_functions/legendre.hpp>
#include <boost/math/tools/roots.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <string_view>
#include <utility>

#include "core/errors.hpp"
#include "core/scene/text.hpp"

namespace crossdyn::flex {

namespace {

constexpr std::array<char, 3> kAxisLetter = {'x', 'y', 'z'};
std::string axis_name(int a) { return std::string(1, kAxisLetter[static_cast<std::size_t>(a)]); }

// sech x = 2 e^-x / (1 + e^-2x): no overflow for large x.
double sech(double x) {
  const double e = std::exp(-std::abs(x));
  return 2 * e / (1 + e * e);
}

// The k-th root of cos x - eps sech x = 0 near `centre`, the zero of cos x it approaches:
// cos x cosh x = eps  <=>  cos x = eps sech x. In [centre - pi/4, centre + pi/4] cos x runs
// monotonically through [-0.71, 0.71] while |sech x| <= sech(pi/4) < 0.76 and decreases, so the
// bracket holds exactly one sign change for every root used (tests/flex checks the first ones
// against published values). TOMS 748 (Alefeld, Potra & Shi 1995) in Boost.Math, to full precision.
double root_near(double eps, double centre) {
  const auto f = [eps](double x) { return std::cos(x) - eps * sech(x); };
  constexpr double kQuarterPi = std::numbers::pi / 4;
  std::uintmax_t iterations = 200;
  const auto r = boost::math::tools::toms748_solve(
      f, centre - kQuarterPi, centre + kQuarterPi,
      boost::math::tools::eps_tolerance<double>(std::numeric_limits<double>::digits), iterations);
  // The bracket is one or two ulps wide: keep the end with the smaller residual.
  return std::abs(f(r.first)) <= std::abs(f(r.second)) ? r.first : r.second;
}

// The constants of one mode's stable form (beam.hpp). With eps = +1 (free-free) or -1 (clamped),
//   phi(x) = cosh x - sigma sinh x + eps (cos x - sigma sin x),
//   sigma  = (cosh l - eps cos l) / (sinh l - eps sin l),     l = lambda.
// Then 1 - sigma = (eps (cos l - sin l) - e^-l) / (sinh l - eps sin l), and with
// sinh l - eps sin l = e^l (1 - e^-2l - 2 eps sin l e^-l) / 2:
//   1 - sigma = 2 G e^-l,   G = (eps (cos l - sin l) - e^-l) / (1 - e^-2l - 2 eps sin l e^-l),
//   cosh x - sigma sinh x = (1 - sigma)/2 e^x + (1 + sigma)/2 e^-x = G e^(x-l) + (1 - G e^-l) e^-x,
// every factor of order one for x in [0, l] (Goncalves, Brennan & Elliott 2007). The denominator
// is 2 e^-l (sinh l - eps sin l) > 0 for l > 0.
struct Mode {
  double lambda, eps, G, B, sigma;
  Mode(bool clamped, double l) : lambda(l), eps(clamped ? -1.0 : 1.0) {
    const double el = std::exp(-l);
    G = (eps * (std::cos(l) - std::sin(l)) - el) / (1 - el * el - 2 * eps * std::sin(l) * el);
    B = 1 - G * el;
    sigma = 1 - 2 * G * el;
  }
  ShapeValue at(double xi) const {
    const double x = lambda * xi;
    const double grow = G * std::exp(x - lambda), decay = B * std::exp(-x);
    const double c = std::cos(x), s = std::sin(x);
    return {grow + decay + eps * (c - sigma * s), lambda * (grow - decay - eps * (s + sigma * c))};
  }
};

// Geometric stiffening (beam.hpp BeamSpec::geometric_stiffening): per node, e = the long axis
// from the clamp to the free end and G_kl = -integral_0^{s} phi_k' phi_l' ds for modes k, l of
// one plane, with phi_k = c_k shape_k(s / L), so phi_k' = (c_k / L) dshape_k/dxi and
// G_kl = -(c_k c_l / L) integral_0^{xi} dshape_k dshape_l dxi. The integral runs node to node
// (xi sorted from the clamp), 16-point Gauss-Legendre on each interval.
void add_foreshortening(const BeamSpec& s, const std::array<int, 2>& across,
                        const std::vector<double>& c, const std::vector<double>& xi, FlexBody& f) {
  const bool from_top = s.boundary == BeamBoundary::ClampedTop;
  Eigen::Vector3d e = Eigen::Vector3d::Zero();
  e(s.axis) = from_top ? -1.0 : 1.0;
  const int n = f.modes();
  // Mode columns per plane, with their Mode objects.
  std::vector<std::vector<int>> plane_cols;
  std::vector<Mode> modes;
  modes.reserve(static_cast<std::size_t>(n));
  for (int d : across) {
    std::vector<int> cols;
    for (int k = 1; k <= s.bending[static_cast<std::size_t>(d)].modes; ++k) {
      cols.push_back(static_cast<int>(modes.size()));
      modes.emplace_back(true, clamped_root(k));
    }
    plane_cols.push_back(std::move(cols));
  }
  // Nodes in order of xi (distance from the clamp).
  std::vector<std::size_t> order(xi.size());
  for (std::size_t j = 0; j < order.size(); ++j) order[j] = j;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return xi[a] < xi[b]; });
  using Gauss = boost::math::quadrature::gauss<double, 16>;
  Eigen::MatrixXd running = Eigen::MatrixXd::Zero(n, n);  // integral_0^{xi} dshape_k dshape_l
  Eigen::VectorXd d(n);
  double prev = 0;
  for (std::size_t j : order) {
    const double a = prev, b = xi[j];
    if (b > a) {
      const double half = (b - a) / 2, mid = (a + b) / 2;
      const auto& abscissa = Gauss::abscissa();
      const auto& weights = Gauss::weights();
      for (std::size_t q = 0; q < abscissa.size(); ++q)
        for (int sign : {-1, 1}) {
          if (abscissa[q] == 0 && sign < 0) continue;
          const double point = mid + sign * half * abscissa[q], w = half * weights[q];
          for (const auto& cols : plane_cols)
            for (int k : cols) d(k) = modes[static_cast<std::size_t>(k)].at(point).dphi;
          for (const auto& cols : plane_cols)
            for (int k : cols)
              for (int l : cols) running(k, l) += w * (d(k) * d(l));  // symmetric to the bit
        }
      prev = b;
    }
    FlexNode& node = f.nodes[j];
    node.e_B = e;
    node.G.resize(n, n);
    for (int k = 0; k < n; ++k)
      for (int l = 0; l < n; ++l)
        node.G(k, l) = -(c[static_cast<std::size_t>(k)] * c[static_cast<std::size_t>(l)] / s.length) *
                       running(k, l);
  }
  f.geometric_stiffening = true;
}

// The mass points (beam.hpp "Mass points"): N points on [-L/2, L/2] in B = ceil(N / 20) blocks
// of equal length (one fewer when that is even and N odd), block sizes palindromic (differing by
// at most one, the middle block taking an odd extra point), each block's points
// and weights Gauss-Legendre: the zeros t of P_n and 2 / ((1 - t^2) P_n'(t)^2), scaled to the
// block. Boost.Math gives the non-negative zeros; the negative ones are their mirror images, and
// each block's centre (j + 1/2 - B/2) L/B is exactly the negative of its mirror block's, so the
// positions are exactly antisymmetric about the CM and mirrored points have equal weights.
// Returns positions x (ascending) and weights w in m (their sum is L to rounding).
constexpr int kMaxBlockPoints = 20;

struct MassPoints {
  std::vector<double> x, w;
};

MassPoints mass_points(int N, double L) {
  int B = (N + kMaxBlockPoints - 1) / kMaxBlockPoints;
  // An even number of blocks holds an even count: for odd N one block fewer (larger blocks are
  // more exact; at most 39 points, N = 39 in one block).
  if (N % 2 == 1 && B % 2 == 0) --B;
  std::vector<int> size(static_cast<std::size_t>(B), N / B);
  int extra = N % B;  // even when B is even
  if (extra % 2 == 1) {
    ++size[static_cast<std::size_t>(B / 2)];  // B odd: the middle block
    --extra;
  }
  for (int p = 0; p < extra / 2; ++p) {
    ++size[static_cast<std::size_t>(p)];
    ++size[static_cast<std::size_t>(B - 1 - p)];
  }
  const double block = L / B, half = block / 2;
  MassPoints out;
  out.x.reserve(static_cast<std::size_t>(N));
  out.w.reserve(static_cast<std::size_t>(N));
  int rule_n = 0;
  std::vector<double> t, wt;  // the rule on [-1, 1], ascending
  for (int j = 0; j < B; ++j) {
    const int n = size[static_cast<std::size_t>(j)];
    if (n != rule_n) {
      rule_n = n;
      std::vector<double> zeros = boost::math::legendre_p_zeros<double>(n);  // >= 0
      std::sort(zeros.begin(), zeros.end());
      std::vector<double> wz;
      for (double z : zeros) {
        const double dp = boost::math::legendre_p_prime(n, z);
        wz.push_back(2 / ((1 - z * z) * dp * dp));
      }
      t.clear();
      wt.clear();
      for (std::size_t i = zeros.size(); i-- > 0;)
        if (zeros[i] > 0) {
          t.push_back(-zeros[i]);
          wt.push_back(wz[i]);
        }
      for (std::size_t i = 0; i < zeros.size(); ++i) {
        t.push_back(zeros[i]);
        wt.push_back(wz[i]);
      }
    }
    const double centre = (j + 0.5 - 0.5 * B) * block;
    for (std::size_t i = 0; i < t.size(); ++i) {
      out.x.push_back(centre + half * t[i]);
      out.w.push_back(half * wt[i]);
    }
  }
  return out;
}

std::string join_problem(const SpecProblem& p) { return p.key + ": " + p.what; }

using scene::shortest;

}  // namespace

bool is_beam_station(const FlexBody& f, std::size_t node) {
  if (node >= f.nodes.size() || f.origin.rfind("beam generator:", 0) != 0) return false;
  const FlexNode& n = f.nodes[node];
  const std::string_view name = n.name;
  return n.mass == 0 && name.size() > 5 && name.substr(0, 5) == "slice" &&
         std::all_of(name.begin() + 5, name.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::vector<int> drop_unused_stations(FlexBody& f, const std::vector<bool>& used) {
  std::vector<int> index(f.nodes.size(), -1);
  std::vector<FlexNode> kept;
  kept.reserve(f.nodes.size());
  for (std::size_t i = 0; i < f.nodes.size(); ++i) {
    if (is_beam_station(f, i) && !(i < used.size() && used[i])) continue;
    index[i] = static_cast<int>(kept.size());
    kept.push_back(std::move(f.nodes[i]));
  }
  f.nodes = std::move(kept);
  return index;
}

double free_free_root(int k) { return root_near(1.0, (2 * k + 1) * std::numbers::pi / 2); }
double clamped_root(int k) { return root_near(-1.0, (2 * k - 1) * std::numbers::pi / 2); }

ShapeValue beam_shape(bool clamped, int k, double xi) {
  return Mode(clamped, clamped ? clamped_root(k) : free_free_root(k)).at(xi);
}

std::vector<SpecProblem> beam_spec_problems(const BeamSpec& s) {
  std::vector<SpecProblem> out;
  const auto bad = [&](std::string key, std::string what) {
    out.push_back({std::move(key), std::move(what)});
  };
  if (!std::isfinite(s.length) || s.length <= 0)
    bad("length", "the beam's length must be positive, found " + shortest(s.length) + " m");
  if (s.axis < 0 || s.axis > 2) {
    bad("axis", "the long axis must be x, y or z");
    return out;
  }
  if (!std::isfinite(s.mass_per_length) || s.mass_per_length <= 0)
    bad("mass_per_length",
        "the mass per length must be positive, found " + shortest(s.mass_per_length) + " kg/m");
  int most_modes = 0, total_modes = 0;
  for (int d = 0; d < 3; ++d) {
    const std::string A = axis_name(d);
    const auto& plane = s.bending[static_cast<std::size_t>(d)];
    const double side = s.section[static_cast<std::size_t>(d)];
    if (d == s.axis) {
      if (side != 0)
        bad("section." + A, "the beam lies along " + A +
                                ": give the section's sides across it only (its length is `length`)");
      if (plane.modes != 0 || plane.EI != 0)
        bad("bending." + A, "the beam lies along " + A + ": it bends along the two other axes only");
      continue;
    }
    if (!std::isfinite(side) || side <= 0)
      bad("section." + A, "the section's side along " + A + " must be positive, found " +
                              shortest(side) + " m");
    if (plane.modes < 0 || plane.modes > kMaxBeamModes)
      bad("bending." + A + ".modes", "the number of modes must be 0 to " +
                                         std::to_string(kMaxBeamModes) + ", found " +
                                         std::to_string(plane.modes));
    else if (plane.modes > 0 && (!std::isfinite(plane.EI) || plane.EI <= 0))
      bad("bending." + A + ".EI",
          "the bending stiffness must be positive, found " + shortest(plane.EI) + " N m^2");
    if (plane.modes > 0 && plane.modes <= kMaxBeamModes) {
      most_modes = std::max(most_modes, plane.modes);
      total_modes += plane.modes;
    }
  }
  if (s.slices < 1 || s.slices > kMaxSlices)
    bad("slices", "the number of slices must be 1 to " + std::to_string(kMaxSlices) + ", found " +
                      std::to_string(s.slices));
  else if (most_modes > 0 && s.slices < 2 * (most_modes + 1))
    bad("slices", std::to_string(s.slices) + " slices cannot resolve mode " +
                      std::to_string(most_modes) + " (about " + std::to_string(most_modes + 1) +
                      " half-waves): use at least " + std::to_string(2 * (most_modes + 1)));
  if (s.normalisation == BeamNormalisation::Top && s.boundary == BeamBoundary::ClampedTop)
    bad("normalisation", "the beam is clamped at the top, where every shape is zero: normalise at "
                         "the bottom or to unit modal mass");
  if (s.normalisation == BeamNormalisation::Bottom && s.boundary == BeamBoundary::ClampedBottom)
    bad("normalisation", "the beam is clamped at the bottom, where every shape is zero: normalise "
                         "at the top or to unit modal mass");
  const BeamDamping& dmp = s.damping;
  if (dmp.kind == BeamDamping::Kind::Ratio) {
    if (dmp.ratios.size() != 1 && dmp.ratios.size() != static_cast<std::size_t>(total_modes))
      bad("damping.ratios", "give one damping ratio for every mode or one per mode (" +
                                std::to_string(total_modes) + "), found " +
                                std::to_string(dmp.ratios.size()));
    for (double z : dmp.ratios)
      if (!std::isfinite(z) || z < 0) {
        bad("damping.ratios", "a damping ratio must be >= 0, found " + shortest(z));
        break;
      }
  } else if (dmp.kind == BeamDamping::Kind::Rayleigh) {
    if (!std::isfinite(dmp.alpha) || dmp.alpha < 0)
      bad("damping.alpha", "Rayleigh alpha must be >= 0, found " + shortest(dmp.alpha) + " 1/s");
    if (!std::isfinite(dmp.beta) || dmp.beta < 0)
      bad("damping.beta", "Rayleigh beta must be >= 0, found " + shortest(dmp.beta) + " s");
  }
  if (s.geometric_stiffening) {
    const double entries = static_cast<double>(2 * s.slices + 2) * total_modes * total_modes;
    if (s.boundary == BeamBoundary::FreeFree)
      bad("geometric_stiffening",
          "geometric stiffening needs a clamped beam (boundary clamped-bottom or clamped-top): "
          "the foreshortening is measured from the clamp");
    else if (total_modes == 0)
      bad("geometric_stiffening", "geometric stiffening needs bending modes");
    else if (entries > kMaxStiffeningEntries)
      bad("geometric_stiffening", "geometric stiffening stores (2 slices + 2) x modes^2 = " +
                                      shortest(entries) + " numbers, more than the limit " +
                                      shortest(kMaxStiffeningEntries) + ": use fewer slices or modes");
  }
  return out;
}

FlexModel make_beam(const BeamSpec& s, const std::string& context) {
  if (const auto problems = beam_spec_problems(s); !problems.empty())
    throw InputError(context + ": " + join_problem(problems.front()));

  const int a = s.axis, N = s.slices;
  const double L = s.length, h = L / N;
  const Eigen::Vector3d e_a = Eigen::Vector3d::Unit(a);
  std::array<int, 2> across{};  // the transverse axes, alphabetical
  for (int d = 0, j = 0; d < 3; ++d)
    if (d != a) across[static_cast<std::size_t>(j++)] = d;

  // Nodes: bottom (0), the stations slice1 .. sliceN (1 .. N), the mass points gauss1 .. gaussN
  // (N + 1 .. 2N), top (2N + 1). Slice centres from the exact half-integers (i + 1/2 - N/2) h and
  // the mass points from mass_points(), so the positions are exactly antisymmetric about the CM.
  const int n_nodes = 2 * N + 2;
  const auto at = [](int j) { return static_cast<std::size_t>(j); };
  std::vector<double> x(at(n_nodes)), mass(x.size(), 0.0);
  x.front() = -L / 2;
  x.back() = L / 2;
  const MassPoints points = mass_points(N, L);
  for (int i = 0; i < N; ++i) {
    x[at(i + 1)] = (i + 0.5 - 0.5 * N) * h;
    x[at(N + 1 + i)] = points.x[at(i)];
    mass[at(N + 1 + i)] = s.mass_per_length * points.w[at(i)];
  }
  // The node sum of the masses (in node order, as rigid_properties adds them) rounds to rho A L
  // as the equal slices' did: the rounding residual goes to the middle point or pair (a change of
  // an ulp or so, which keeps the mirror pairs equal).
  {
    const double target = s.mass_per_length * L;
    for (int pass = 0; pass < 4; ++pass) {
      double total = 0;
      for (double m : mass) total += m;
      const double delta = target - total;
      if (delta == 0) break;
      if (N % 2 == 1) {
        mass[at(N + 1 + N / 2)] += delta;
      } else {
        mass[at(N + N / 2)] += delta / 2;
        mass[at(N + 1 + N / 2)] += delta / 2;
      }
    }
  }
  // xi = s / L along the shape's coordinate (from the clamped end; from bottom for free-free), and
  // dxi/dx_a. The ends and the stations from their index (the stations' values as before the mass
  // points moved: their shapes are unchanged), the mass points from their position.
  const bool clamped = s.boundary != BeamBoundary::FreeFree;
  const bool from_top = s.boundary == BeamBoundary::ClampedTop;
  std::vector<double> xi(x.size());
  for (int j = 0; j < n_nodes; ++j) {
    double up;  // from bottom
    if (j == 0) up = 0.0;
    else if (j == n_nodes - 1) up = 1.0;
    else if (j <= N) up = (j - 0.5) / N;
    else up = 0.5 + x[at(j)] / L;
    double down;  // from top
    if (j == 0) down = 1.0;
    else if (j == n_nodes - 1) down = 0.0;
    else if (j <= N) down = (N - j + 0.5) / N;
    else down = 0.5 - x[at(j)] / L;
    xi[at(j)] = from_top ? down : up;
  }
  const double dxi_dx = (from_top ? -1.0 : 1.0) / L;

  // A mass point's own inertia: its section's (the box of sides section[d] across, none along a:
  // the points' parallel-axis terms integrate x_a^2 exactly from 2 points per block on). One point
  // (N = 1) at the centre cannot: it keeps the whole box's m L^2 / 12 along a.
  Eigen::Vector3d sq;
  for (int d = 0; d < 3; ++d) {
    const double side = d == a ? (N == 1 ? L : 0.0) : s.section[at(d)];
    sq(d) = side * side;
  }
  const Eigen::Vector3d J_per_kg = Eigen::Vector3d(sq(1) + sq(2), sq(0) + sq(2), sq(0) + sq(1)) / 12.0;

  int n_modes = 0;
  for (int d : across) n_modes += s.bending[at(d)].modes;

  FlexModel out;
  FlexBody& f = out.flex;
  f.nodes.resize(at(n_nodes));
  for (int j = 0; j < n_nodes; ++j) {
    FlexNode& node = f.nodes[at(j)];
    if (j == 0) node.name = "bottom";
    else if (j == n_nodes - 1) node.name = "top";
    else if (j <= N) node.name = "slice" + std::to_string(j);
    else node.name = "gauss" + std::to_string(j - N);
    node.mass = mass[at(j)];
    node.p_BoNi_B = Eigen::Vector3d::Zero();  // not x * e_a: no -0 across the axis
    node.p_BoNi_B(a) = x[at(j)];
    node.J_Ni_B = node.mass > 0 ? Eigen::Matrix3d((node.mass * J_per_kg).asDiagonal())
                                : Eigen::Matrix3d::Zero();
    node.Phi_B = Eigen::Matrix3Xd::Zero(3, n_modes);
    node.Psi_B = Eigen::Matrix3Xd::Zero(3, n_modes);
  }
  f.K = Eigen::MatrixXd::Zero(n_modes, n_modes);
  f.D = Eigen::MatrixXd::Zero(n_modes, n_modes);

  // The end whose displacement is the modal coordinate (and the sign reference for unit mass).
  const BeamNormalisation norm = s.normalisation;
  const bool at_top = norm == BeamNormalisation::Top ||
                      ((norm == BeamNormalisation::Auto || norm == BeamNormalisation::Mass) && !from_top);
  const int ref_node = at_top ? n_nodes - 1 : 0;

  std::vector<double> phi(x.size()), dphi(x.size());
  std::vector<double> norm_constants;  // c per mode column, for the foreshortening
  int col = 0;
  for (int d : across) {
    const BeamPlane& plane = s.bending[static_cast<std::size_t>(d)];
    const Eigen::Vector3d e_d = Eigen::Vector3d::Unit(d), e_rot = e_a.cross(e_d);
    for (int k = 1; k <= plane.modes; ++k, ++col) {
      const Mode mode(clamped, clamped ? clamped_root(k) : free_free_root(k));
      double sum_m_phi2 = 0;
      for (std::size_t j = 0; j < x.size(); ++j) {
        const ShapeValue v = mode.at(xi[j]);
        phi[j] = v.phi;
        dphi[j] = v.dphi;
        sum_m_phi2 += mass[j] * v.phi * v.phi;
      }
      const double end_value = phi[static_cast<std::size_t>(ref_node)];
      const double c = norm == BeamNormalisation::Mass
                           ? std::copysign(1.0 / std::sqrt(sum_m_phi2), end_value)
                           : 1.0 / end_value;
      norm_constants.push_back(c);
      double M_k = 0;
      for (std::size_t j = 0; j < x.size(); ++j) {
        FlexNode& node = f.nodes[j];
        node.Phi_B.col(col) = (c * phi[j]) * e_d;
        node.Psi_B.col(col) = (c * dphi[j] * dxi_dx) * e_rot;
        M_k += mass[j] * (c * phi[j]) * (c * phi[j]);
      }
      const double omega = mode.lambda * mode.lambda * std::sqrt(plane.EI / (s.mass_per_length * L * L * L * L));
      f.K(col, col) = omega * omega * M_k;
      switch (s.damping.kind) {
        case BeamDamping::Kind::None: break;
        case BeamDamping::Kind::Ratio: {
          const auto& z = s.damping.ratios;
          const double zeta = z.size() == 1 ? z[0] : z[static_cast<std::size_t>(col)];
          f.D(col, col) = 2 * zeta * omega * M_k;
          break;
        }
        case BeamDamping::Kind::Rayleigh:
          f.D(col, col) = s.damping.alpha * M_k + s.damping.beta * f.K(col, col);
          break;
      }
      // Appended piecewise: GCC 12 at -O3 reports a false -Warray-bounds / -Wstringop-overflow in
      // the inlined `const char* + std::string&&` (GCC bugs 105329, 105651; fixed in GCC 13).
      std::string name = "q";
      name += axis_name(d);
      name += std::to_string(k);
      f.mode_names.push_back(std::move(name));
    }
  }

  if (s.geometric_stiffening) add_foreshortening(s, across, norm_constants, xi, f);

  static constexpr const char* kBoundary[] = {"free-free", "clamped at the bottom",
                                              "clamped at the top"};
  f.origin = "beam generator: length " + shortest(L) + " m along " + axis_name(a) + ", " +
             std::to_string(N) + " slices, " + kBoundary[static_cast<int>(s.boundary)] + ", " +
             std::to_string(n_modes) + " modes, " +
             (norm == BeamNormalisation::Mass
                  ? std::string("unit modal mass")
                  : std::string("unit displacement at the ") + (at_top ? "top" : "bottom") + " end");

  const RigidProperties r = rigid_properties(f);
  out.mass = r.mass;
  out.I_BBo_B = r.I;
  validate_flex(f, context);
  return out;
}

}  // namespace crossdyn::flex
