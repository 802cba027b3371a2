// The free joint: the base's six degrees of freedom (joints[0] only; core/scene/topology.hpp). In
// maximal coordinates the base's motion is its body's own state, so the unit (joint_unit.hpp) has
// no rows (constraint_rows() returns at once), coordinates, load or outputs.
#include "formulations/newton_euler/joints/joint_unit.hpp"

namespace crossdyn::newton_euler {

namespace {

void model(const Joint& /*joint*/, JointModel& m) { m.rows = 0; }

}  // namespace

const JointUnit kFreeJoint{"free",  model,   nullptr, nullptr, nullptr, nullptr, nullptr, nullptr,
                           nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr};

}  // namespace crossdyn::newton_euler
