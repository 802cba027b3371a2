// The choice of a joint's unit (joint_unit.hpp) from the scene's JointType: the Newton-Euler
// engine's one switch on the joint type, made once per joint when its JointModel is built.
#include "formulations/newton_euler/joints/joint_unit.hpp"

namespace crossdyn::newton_euler {

const JointUnit& joint_unit(JointType type) {
  switch (type) {
    case JointType::Free: return kFreeJoint;
    case JointType::Revolute: return kRevoluteJoint;
    case JointType::Spherical: return kSphericalJoint;
    case JointType::Prismatic: return kPrismaticJoint;
    case JointType::Universal: return kUniversalJoint;
    case JointType::Fixed: return kFixedJoint;
  }
  return kFreeJoint;  // not reached: every JointType is listed above (-Wswitch)
}

}  // namespace crossdyn::newton_euler
