// The one dispatch on JointType of the kane engine's joint units (joint_unit.hpp).
#include "formulations/kane/joints/joint_unit.hpp"

namespace crossdyn::kane {

const JointUnit& joint_unit(JointType type) {
  switch (type) {
    case JointType::Free:
      return free_joint_unit();
    case JointType::Revolute:
      return revolute_joint_unit();
    case JointType::Spherical:
      return spherical_joint_unit();
    case JointType::Prismatic:
      return prismatic_joint_unit();
    case JointType::Universal:
      return universal_joint_unit();
    case JointType::Fixed:
      break;
  }
  return fixed_joint_unit();
}

}  // namespace crossdyn::kane
