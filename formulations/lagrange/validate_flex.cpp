// Checks of the System before the Lagrange engine's model is built (build_model.cpp): what the
// engine cannot run in flexible bodies and joints at nodes, or what would make its mass matrix
// singular (README.md, "Flexible bodies").
#include <Eigen/Eigenvalues>
#include <string>

#include "core/errors.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/joints/joint_unit.hpp"
#include "formulations/lagrange/messages.hpp"
#include "formulations/lagrange/model.hpp"

namespace crossdyn::lagrange {

// What the engine cannot run, or what would make its mass matrix singular: InputError naming the
// scene file, the body or joint and the reason.
void validate_flex(const System& system, const std::string& where) {
  for (const Body& b : system.bodies) {
    if (!b.flex) continue;
    const FlexBody& f = *b.flex;
    const std::string body = "bodies: body '" + b.name + "' (flexible): ";
    const auto n = static_cast<Eigen::Index>(f.modes());
    if (f.nodes.empty()) throw InputError(where + body + "has no nodes");
    if (f.K.rows() != n || f.K.cols() != n || f.D.rows() != n || f.D.cols() != n)
      throw InputError(where + body + "K and D must be " + std::to_string(n) + " x " +
                       std::to_string(n) + " (one row and column per mode)");
    if (!f.K.allFinite() || !f.D.allFinite())
      throw InputError(where + body + "K or D has a non-finite entry");
    for (const FlexNode& node : f.nodes) {
      if (node.Phi_B.cols() != n || node.Psi_B.cols() != n)
        throw InputError(where + body + "node '" + node.name + "' must have " +
                         std::to_string(n) + " mode shapes and slopes");
      if (f.geometric_stiffening && node.G.size() > 0 &&
          (node.G.rows() != n || node.G.cols() != n || !node.G.allFinite() || !node.e_B.allFinite()))
        throw InputError(where + body + "node '" + node.name + "' must have a finite " +
                         std::to_string(n) + " x " + std::to_string(n) +
                         " geometric stiffening matrix G and a finite direction e");
      if (!(node.mass >= 0) || !node.p_BoNi_B.allFinite() || !node.J_Ni_B.allFinite() ||
          !node.Phi_B.allFinite() || !node.Psi_B.allFinite())
        throw InputError(where + body + "node '" + node.name +
                         "' has a negative mass or a non-finite value");
    }
    // M_B(0) must be positive definite, or M is singular at zero deformation.
    const FlexInvariants inv(f, 1.0);
    const Eigen::VectorXd lambda =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(inv.mass_matrix_at_rest(),
                                                       Eigen::EigenvaluesOnly)
            .eigenvalues();
    if (!(lambda.minCoeff() > 1e-12 * lambda.maxCoeff()))
      throw InputError(where + body +
                       "the mass matrix of its rigid motion and modes is singular at zero "
                       "deformation (eigenvalues from " +
                       format_number(lambda.minCoeff()) + " to " +
                       format_number(lambda.maxCoeff()) +
                       "): a mode has no kinetic energy, or repeats a rigid-body motion or "
                       "another mode");
  }
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    const std::string joint = "joints: joint '" + J.name + "': ";
    auto check_side = [&](int body, int node, const Eigen::Vector3d& point, const char* side,
                          const char* key) {
      if (node < 0) return;
      if (body < 0) throw InputError(where + joint + "a free joint has no " + side + " node");
      const Body& B = system.bodies[static_cast<std::size_t>(body)];
      if (!B.flex)
        throw InputError(where + joint + "attaches at node " + std::to_string(node) + " of its " +
                         side + " '" + B.name + "', which is rigid (no nodes)");
      if (node >= static_cast<int>(B.flex->nodes.size()))
        throw InputError(where + joint + "node index " + std::to_string(node) + " of its " +
                         side + " '" + B.name + "' is out of range (" +
                         std::to_string(B.flex->nodes.size()) + " nodes)");
      const FlexNode& nd = B.flex->nodes[static_cast<std::size_t>(node)];
      if ((point - nd.p_BoNi_B).norm() > 1e-9 * (1.0 + nd.p_BoNi_B.norm()))
        throw InputError(where + joint + key + " " + format_vector(point) +
                         " is not the undeformed position " + format_vector(nd.p_BoNi_B) +
                         " of node '" + nd.name + "' of body '" + B.name + "'");
    };
    const JointUnit& unit = joint_unit(J.type);
    if (!unit.at_nodes && (J.child_node >= 0 || (J.parent >= 0 && J.parent_node >= 0)))
      throw InputError(where + joint + unit.no_nodes);
    check_side(J.parent, J.parent_node, J.p_PoJ_P, "parent", "parent_point");
    if (unit.at_nodes) check_side(J.child, J.child_node, J.p_CoJ_C, "child", "child_point");
  }
}


}  // namespace crossdyn::lagrange
