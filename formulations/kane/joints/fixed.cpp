// The fixed joint: no position, no speed; the child moves with its parent.
#include "formulations/kane/joints/joint_unit.hpp"

#include "formulations/kane/kane_engine.hpp"

namespace crossdyn::kane {
namespace {

void sizes(bool /*prescribed*/, int& nqj, int& nuj) {
  nqj = 0;
  nuj = 0;
}

void labels(const Node&, int, const std::string&, const std::string&, std::vector<std::string>&) {}
void q_rates(const Node&, const double*, const double*, double*) {}
void pack(const Node&, const TreeState&, const TreeState::JointState&, double*, double*) {}
void accel(const Node&, const NodeWork&, const Eigen::VectorXd&, TreeAccel&) {}

double spring_energy(const Node&, const Joint&, const double*) { return 0.0; }
void output(const Node&, const NodeWork&, double, const double*, const double*, RowWriter&) {}

// R_NJc = R_NJ0: the child frame is the offset frame; no speed, no relative motion.
void position(const Node&, const double*, const Eigen::Matrix3d&, const Eigen::Matrix3d& R_NJ0,
              Eigen::Matrix3d& R_NJc, NodeWork&, Eigen::Vector3d&) {
  R_NJc = R_NJ0;
}
void velocity(const Node&, const double*, NodeWork& w) { w.w_PC_N.setZero(); }

}  // namespace

const JointUnit& fixed_joint_unit() {
  static const JointUnit unit{sizes,  -1,      labels,   q_rates,  pack,    accel,   spring_energy,
                              output, nullptr, position, velocity, nullptr, nullptr, JointShape::None};
  return unit;
}

}  // namespace crossdyn::kane
