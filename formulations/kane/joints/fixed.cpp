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

double spring_energy(const Node&, double, double, const double*) { return 0.0; }
void output(const Node&, const NodeWork&, double, const double*, const double*, RowWriter&) {}

}  // namespace

const JointUnit& fixed_joint_unit() {
  static const JointUnit unit{sizes, -1, labels, q_rates, pack, accel, spring_energy, output};
  return unit;
}

}  // namespace crossdyn::kane
