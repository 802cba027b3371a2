// The beam generator: a uniform Euler-Bernoulli beam as a flexible body (docs/flexible-data.md
// "Beam generator"; docs/scenarios.md "Beam generator"; issue 11 "Sources of modal data").
//
// Geometry. The beam lies along one body axis a (the long axis), centred on the body origin Bo
// (its undeformed CM): it spans x_a in [-L/2, +L/2]. The end at +L/2 is the node `top`, the end at
// -L/2 the node `bottom` (whatever the axis). `slices` = N divides the beam into N slices of
// length h = L/N, and the station `slice<i>` (i = 1..N from bottom to top) sits at the slice
// centre x_a = -L/2 + (i - 1/2) h. The ends and the stations are massless: they are where joints
// attach (a scene names them), at the same places as when the slices carried the mass.
//
// Mass points. The mass sits at N nodes `gauss<i>` (i = 1..N from bottom to top) placed and
// weighted by composite Gauss-Legendre quadrature: B = ceil(N / 20) blocks of equal length (one
// fewer when that is even and N odd), palindromic block sizes (so the layout is exactly
// antisymmetric about the CM), in each block of n points the zeros t of P_n and the weights
// 2 / ((1 - t^2) P_n'(t)^2) (Boost.Math), scaled to the block: m_i = rho A w_i. Every node sum
// sum_i m_i f(x_i) is then the integral of rho A f over the beam to rounding for the smooth f of
// the modal data (a block of n points is exact for polynomials of degree 2n - 1): the modal
// masses rho A integral phi_k phi_l, the couplings integral phi_k and integral x phi_k (zero for
// free-free modes), and the rigid mass and inertia. The beam's modal data are the continuum
// beam's, not a sliced approximation, from about 10 points per half-wave of the highest mode
// (tests/flex/test_beam.cpp: the free body's frequencies equal the closed form to 1e-12 from
// N = 12 with two modes per plane; the modal masses equal rho A L / 4 to 1e-13 from N = 21).
// Each mass point carries only its section's own inertia J_i = m_i/12 diag(...) (the box of the
// section's sides across a, none along a: the points' parallel-axis terms m_i x_i^2 integrate
// x_a^2 exactly from two points per block); one point (N = 1) keeps the whole box's m L^2/12
// along a. The rounding residual of sum m_i against rho A L goes to the middle point (pair).
// The nodes are in that order: bottom, slice1 .. sliceN, gauss1 .. gaussN, top. The scene reader
// drops the stations no joint names (drop_unused_stations: they carry no mass, so nothing
// depends on them, and each would cost the engines time).

// Bending. The two transverse axes, in alphabetical order (a = z: x, y; a = y: x, z; a = x: y, z),
// are the bending directions d: "the plane of d" is the plane spanned by d and a, and its modes
// displace the centre line along d, named q<d><k> (qx1, qx2, ... then qy1, ...). Sections translate
// with the centre line and keep their orientation (no rotary inertia from slope), so a node's mode
// shape is Phi = c phi(s) e_d and its mode slope, the small rotation of the section that turns the
// axis e_a to the tangent e_a + (du/dx_a), is Psi = c (dphi/dx_a) (e_a x e_d): in the x-z plane of a
// beam along z a displacement along +x with positive slope is a rotation about +y; in the y-z
// plane, about -x.
//
// Modes (Blevins, "Formulas for Natural Frequency and Mode Shape", 1979, Table 8-1), s the coordinate along the beam from the clamped
// end (from `bottom` for free-free), x = b s, lambda = b L:
//   free-free   phi = cosh x + cos x - sigma (sinh x + sin x),
//               sigma = (cosh lambda - cos lambda) / (sinh lambda - sin lambda),
//               cos lambda cosh lambda = 1   (lambda = 4.730040744862704, 7.853204624095838, ...)
//   clamped     phi = cosh x - cos x - sigma (sinh x - sin x),
//               sigma = (cosh lambda + cos lambda) / (sinh lambda + sin lambda),
//               cos lambda cosh lambda = -1  (lambda = 1.875104068711961, 4.694091132974175, ...)
//   omega_k = lambda_k^2 sqrt(EI / (rho A L^4)).
// The roots are found to machine precision by TOMS 748 (Boost.Math) on cos x -/+ sech x, bracketed
// around the asymptote (2k+1) pi/2 (free-free) or (2k-1) pi/2 (clamped). The shapes are evaluated
// in the cancellation-free form of Goncalves, Brennan & Elliott ("Numerical evaluation of
// high-order modes of vibration in uniform Euler-Bernoulli beams", J. Sound Vib. 301, 2007): cosh x - sigma sinh x = G e^(x - lambda) + (1 - G e^-lambda) e^-x with
// 1 - sigma = 2 G e^-lambda computed without forming sigma from cosh/sinh (see beam.cpp), so modes
// of any order have every term of order one (no overflow, no loss of digits near sigma -> 1).
//
// Normalisation and modal mass. Each shape is scaled by c, by default to unit displacement along
// +d at the `top` end (at `bottom` when clamped at the top): the paper's Example 2 convention, "a
// modal coordinate is that end's deflection, in m". Or to unit modal mass (1 kg). The modal mass
// is the NODE SUM M_k = sum_i m_i |Phi_ik|^2 (the mass the engines integrate), which the mass
// points make the continuum's integral (rho A L / 4 with a unit end value, |phi(end)| = 2), and
// K_k = omega_k^2 M_k: the discrete free body vibrates at omega_k to rounding at any slicing
// that resolves the modes (before issue 27 the slices' midpoint sums put it off by O(h^4), and
// their mode/rigid couplings by O(h^2)).
// K and D are diagonal; D_k = 2 zeta_k omega_k M_k (damping ratios) or D_k = alpha M_k + beta K_k
// (Rayleigh).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/flex/flex_model.hpp"

namespace crossdyn::flex {

enum class BeamBoundary { FreeFree, ClampedBottom, ClampedTop };
enum class BeamNormalisation { Auto, Top, Bottom, Mass };  // Auto: Top, or Bottom if clamped at top

struct BeamDamping {
  enum class Kind { None, Ratio, Rayleigh };
  Kind kind = Kind::None;
  std::vector<double> ratios;  // Ratio: one for every mode, or one per mode in mode order
  double alpha = 0;            // Rayleigh D = alpha M + beta K: alpha in 1/s
  double beta = 0;             //                                 beta in s
};

// One bending plane, named by its displacement direction d (BeamSpec::bending[d]).
struct BeamPlane {
  int modes = 0;    // number of modes (0 allowed)
  double EI = 0;    // bending stiffness for displacement along d, N m^2 (needed when modes > 0)
};

struct BeamSpec {
  double length = 0;                    // L, m
  int axis = 2;                         // long axis: 0 x, 1 y, 2 z
  double mass_per_length = 0;           // rho A, kg/m
  std::array<double, 3> section{};      // box sides along each body axis, m; 0 along the long axis
  std::array<BeamPlane, 3> bending{};   // by displacement axis; no modes along the long axis
  BeamBoundary boundary = BeamBoundary::FreeFree;
  int slices = 100;                     // N
  BeamNormalisation normalisation = BeamNormalisation::Auto;
  BeamDamping damping;
  // Geometric stiffening (clamped beams only): every node carries the foreshortening
  // e (1/2 eta^T G eta) of system.hpp's FlexNode, with e the unit long axis pointing from the
  // clamp to the free end and, for node i at distance s_i from the clamp,
  //   G_i,kl = - integral_0^{s_i} phi_k'(s) phi_l'(s) ds       (modes k, l of one plane; 0 across
  //   planes), phi_k the normalised shape of mode k: the centre line's length is kept to second
  //   order, so a node moves towards the clamp by 1/2 integral_0^{s_i} |u'|^2 ds (Kane, Ryan and
  //   Banerjee 1987, Eq. (8)). Integrated by 16-point Gauss-Legendre (Boost.Math) between
  //   consecutive nodes (ends, stations and mass points in order from the clamp), to rounding;
  //   the sums are written w (d_k d_l), so each G_i is symmetric to the bit.
  bool geometric_stiffening = false;
};

// What is wrong with a spec: the key (relative to the beam block of a scene, as in
// docs/flexible-data.md: "length", "bending.x.EI", "damping.ratios", ...) and what. The scene
// reader maps the key to its line and column.
struct SpecProblem {
  std::string key;
  std::string what;
};
std::vector<SpecProblem> beam_spec_problems(const BeamSpec& spec);

// Limits (docs/flexible-data.md): slices 1 .. kMaxSlices and at least 2 (k + 1) for a plane's
// highest mode k (two nodes per half-wave; the integrals are exact to rounding only from about
// ten per half-wave); at most kMaxBeamModes modes per plane.
inline constexpr int kMaxSlices = 50000;  // 2 N + 2 nodes (beam.hpp "Nodes"), within kMaxNodes
inline constexpr int kMaxBeamModes = 100;
// Geometric stiffening stores an n x n matrix per node (2 N + 2 nodes before the reader drops
// unused stations): at most this many entries in all.
inline constexpr double kMaxStiffeningEntries = 8e6;  // 64 MB

// The beam's nodes, modes, K and D, with its rigid mass and inertia. Throws InputError
// "<context>: <key>: <what>" for the first of beam_spec_problems(); validate_flex passes on the
// result.
FlexModel make_beam(const BeamSpec& spec, const std::string& context);

// A station of a generated beam (beam.hpp "Nodes"): a massless `slice<i>` node of a body whose
// origin is the beam generator. Stations exist so that joints attach where they always did; no
// output depends on one that no joint uses (it carries no mass), but each costs the engines time
// (geometric stiffening loops over every node per right-hand side).
bool is_beam_station(const FlexBody& f, std::size_t node);

// Removes the stations of `f` (is_beam_station) whose `used` entry is false (`used` has one
// entry per node); every other node stays, in order. Returns each old node's new index, -1 for a
// removed one. The scene reader calls it with the nodes its joints name.
std::vector<int> drop_unused_stations(FlexBody& f, const std::vector<bool>& used);

// The k-th root (k >= 1) lambda_k = b_k L of the frequency equation: free-free cos cosh = 1 (the
// elastic roots, 0 excluded), clamped-free cos cosh = -1. Machine precision, any k.
double free_free_root(int k);
double clamped_root(int k);

// The unnormalised closed-form shape of mode k and its derivative at xi = s / L in [0, 1]
// (s from the clamped end; from either end for free-free), in the stable form; normalised as
// the classical forms above, so that the integral of phi^2 over xi in [0, 1] is 1.
struct ShapeValue {
  double phi;     // phi(xi)
  double dphi;    // d phi / d xi
};
ShapeValue beam_shape(bool clamped, int k, double xi);

}  // namespace crossdyn::flex
