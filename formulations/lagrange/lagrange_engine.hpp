// The Lagrange engine: Lagrange's equations in quasi-coordinates (Boltzmann-Hamel form), with the
// coordinates of MBODY (reference paper, Eqs. 15-23). Internal header: the harness uses only the
// factory in lagrange.hpp; tests use the inspection methods below.
//
// The derivation (coordinates q* and quasi-velocities pi', flexible bodies, the equations of
// motion, the passes, Euler-angle charts and re-charting) and the file implementing each equation:
// formulations/lagrange/README.md. State x = (q*, pi'), size 2n; with prescribed joints, the free
// part only.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "core/engine.hpp"

namespace crossdyn::lagrange {

inline constexpr double kDeg = std::numbers::pi / 180.0;  // one degree in radians
inline constexpr double kPackDeg = 60.0;     // pack(): keep the default chart up to this |a2|
inline constexpr double kRechartDeg = 75.0;  // after_step(): re-chart beyond this |a2|
inline constexpr double kFailDeg = 89.0;     // rechart == false: stop beyond this |a2|

class LagrangeEngine final : public Engine {
 public:
  LagrangeEngine(const System& system, const EngineOptions& options);
  ~LagrangeEngine() override;
  LagrangeEngine(const LagrangeEngine&) = delete;
  LagrangeEngine& operator=(const LagrangeEngine&) = delete;

  const char* name() const override { return "lagrange"; }
  int state_size() const override;
  std::string state_label(int i) const override;
  void pack(const TreeState& s, double* x) override;
  void rhs(double t, const double* x, double* xdot) override;
  bool after_step(double t, double* x) override;
  void accelerations(double t, const double* x, TreeAccel& a) override;
  // Exact, by nested forward-mode AD through the engine's kinematics and energies (tangent.cpp):
  // every system (false only if its values disagreed with accelerations()).
  bool accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds, TreeAccel& a,
                             TreeAccel& da) override;
  // Exact, by the same means (tangent.cpp, output_tangent.cpp; README.md "Exact linearisation"):
  // every system, every column; false only if its values disagreed with rhs() or output_row().
  bool rhs_tangent(double t, const double* x, const double* dx, double* xdot, double* dxdot) override;
  const OutputLayout& layout() const override;
  void output_row(double t, const double* x, double* row) override;
  bool output_row_tangent(double t, const TreeState& s, const TreeTangent& ds, double* row,
                          double* drow) override;
  // The system the solve pass factors at (t, x), in the chart x is in (the workspace's current
  // charts; nothing is re-charted): A = M (d2T/dpi'2, symmetric), b = N + B^T dL/dq* - (dM/dt) pi'
  // - B^T W^T p (paper Eq. 23; Whittaker 1944, Ch. II; Meirovitch 1970, Ch. 4), z = pi'', i.e.
  // speed_index = nf ... 2 nf - 1. With prescribed joints, the free block the engine solves
  // (solve.cpp; README.md, "Solve"): A = M_ff, b = f_f - M_fc theta''. Allocates.
  LinearSystem linear_system(double t, const double* x) override;

  // ---- Inspection (tests, reports) ----
  // The state x holds the free coordinates and quasi-velocities only; a prescribed joint's angle
  // and rate come from its profile at t (docs/prescribed-motion.md). Methods below taking a state
  // x take the time t for that (ignored when nothing is prescribed).
  int dof() const;                           // the number of free quasi-velocities (x is 2 dof())
  long recharts() const;                     // charts switched since construction
  long lock_crossings() const;               // of which after a lock crossed within a step
  int euler_sets() const;                    // number of Euler-angle sets
  std::string euler_set_owner(int s) const;  // "main" (base body) or the spherical joint's name
  int chart(int s) const;                    // current chart of set s (index into kSequences)
  std::string chart_name(int s) const;       // "3-2-1", ...
  int modal_index(int body) const;           // index of a flexible body's eta in x (-1: rigid)
  // Every term of the equations of motion at (t, x) (README.md, "Equations of motion").
  struct Terms {
    Eigen::MatrixXd M;       // mass matrix d2T/dpi'2
    Eigen::VectorXd p;       // dT/dpi'
    Eigen::VectorXd Mdot_u;  // (dM/dt) pi'
    Eigen::VectorXd hamel;   // B^T W^T p
    Eigen::VectorXd dL;      // B^T d(T - V)/dq*
    Eigen::VectorXd N;       // generalised forces
    Eigen::VectorXd qdot;    // q*' = B pi'
    Eigen::VectorXd udot;    // pi''
  };
  // Terms are over every coordinate, prescribed ones included (udot: theta'' there).
  Terms terms(double t, const double* x);
  double kinetic_energy(const double* x, double t = 0.0);
  // The springs', the flexible bodies' elastic and the environment's potential at t (gravity.cpp).
  double potential_energy(const double* x, double t = 0.0);
  // On an orbit: O, the system's CM at t = 0 from the scene's initial state (N, fixed in N).
  Eigen::Vector3d orbit_reference_N() const;
  Eigen::Vector3d angular_momentum_N(const double* x, double t = 0.0);  // about the system CM, N
  Eigen::Vector3d linear_momentum_N(const double* x, double t = 0.0);
  // Torques of the prescribed revolute joints at (t, x), System::joints order (0 for the others).
  std::vector<double> prescribed_torques(double t, const double* x);

  struct Model;      // immutable, built from the System (model.hpp, build_model.cpp)
  struct Workspace;  // mutable scratch and the current charts (workspace.hpp)

 private:
  // Below, xf is the full (q*, pi'), prescribed coordinates included (expand).
  const double* expand(double t, const double* x);  // state x => xf at t (x itself if none)
  void evaluate(double t, const double* xf);  // (t, xf) => every term and pi'' in the workspace
  void prepare_charts(double t, const double* xf);
  std::string full_label(int i) const;  // label of index i of xf
  // tangent.cpp: pack(s) into xs and the full (q*, pi')'s variation along ds (2n values); throws
  // InputError naming `caller` for a malformed tangent, before anything is written.
  void pack_tangent(const TreeState& s, const TreeTangent& ds, const char* caller, double* xs,
                    std::vector<double>& dxf);
  double kinetic_energy_full(const double* xf);
  double potential_energy_full(const double* xf);
  Eigen::Vector3d angular_momentum_full(const double* xf);
  Eigen::Vector3d linear_momentum_full(const double* xf);
  std::unique_ptr<const Model> model_;
  std::unique_ptr<Workspace> ws_;
};

}  // namespace crossdyn::lagrange
