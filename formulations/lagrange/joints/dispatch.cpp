// The one dispatch on JointType of the Lagrange engine: a joint's unit (joint_unit.hpp), chosen
// once per joint when the model is built (build_model.cpp).
#include "formulations/lagrange/joints/joint_unit.hpp"

namespace crossdyn::lagrange {

// Defined in joints/<type>.cpp.
extern const JointUnit kFreeJoint, kRevoluteJoint, kSphericalJoint, kFixedJoint, kPrismaticJoint,
    kUniversalJoint;

const JointUnit& joint_unit(JointType type) {
  switch (type) {
    case JointType::Free:
      return kFreeJoint;
    case JointType::Revolute:
      return kRevoluteJoint;
    case JointType::Spherical:
      return kSphericalJoint;
    case JointType::Prismatic:
      return kPrismaticJoint;
    case JointType::Universal:
      return kUniversalJoint;
    case JointType::Fixed:
      break;
  }
  return kFixedJoint;
}

}  // namespace crossdyn::lagrange
