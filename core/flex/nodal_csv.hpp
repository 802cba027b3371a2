// Nodal data files: how users bring a finite-element model's modes (docs/flexible-data.md
// "Nodal data files"; the same way 42 and TREETOPS take NASTRAN-derived data).
//
// Two CSV files, header-driven (columns in any order), '#' comment lines and blank lines allowed,
// fields separated by ',' with surrounding spaces ignored, no quoting (names are identifiers and
// values plain numbers: "1.5", "-2e-3", "+1.0E+00"). SI units.
//
//   nodes file, one row per node:
//     name                   node name (identifier, unique): joints attach by it
//     mass                   kg, >= 0 (0: an attachment point), positive total
//     x, y, z                undeformed position in the body's reference frame R, m
//     Jxx, Jyy, Jzz, Jxy, Jxz, Jyz
//                            optional (all six or none): the node's rigid inertia about itself,
//                            body axes, tensor components (Jxy = -integral x y dm), kg m^2
//     <mode>.ux, .uy, .uz    per mode: the mode shape (translation per unit modal coordinate)
//     <mode>.rx, .ry, .rz    per mode: the mode slope (small rotation vector per unit coordinate)
//   The modes are named by the column prefixes, in the order they first appear in the header.
//
//   modes file, one row per mode, in the nodes file's mode order:
//     mode                   the mode name
//     then EITHER  frequency_hz [, damping_ratio]       (the FE eigen-solution: K and D diagonal,
//                  K_k = (2 pi f_k)^2 M_k, D_k = 2 zeta_k (2 pi f_k) M_k, M_k = sum_i m_i |Phi_ik|^2
//                  the nodes' modal mass, so the discrete body vibrates at f_k: core/flex/beam.hpp)
//     OR           K.<mode> for every mode [, D.<mode> for every mode]   (rows of K and D)
//     (frequency_hz with D.<mode> columns is also accepted: K from the frequencies, D as given).
//
// The CM. Positions are in the body's reference frame R (the FE model's origin, body axes). The
// reader shifts every node to the nodes' CM, p_BoNi_B = p_RoNi_R - p_RoBo_R with
// p_RoBo_R = sum m_i p_RoNi_R / m, and returns p_RoBo_R (FlexModel) for information. In a scene
// (docs/scene-format.md) rigid joint points on a flexible body (parent_point/child_point without
// a node) are measured from that CM, Bo, as on a rigid body without `center_of_mass`; a joint at
// a node names the node (parent_node/child_node) and takes its position. Shapes, slopes and J
// are not changed by the shift.
//
// A small strict parser rather than a CSV library: Debian's libcsv (C, RFC 4180, callbacks, no
// line/column positions) and libfccp (fast-cpp-csv-parser: column count fixed at compile time)
// were considered; neither reports positions as the project's messages need, and the format has
// no quoting to handle. Every error is an InputError "<file>:<line>:<column>: column '<name>':
// <what is wrong>" (or "<file>: <what>" for whole-file properties such as K's definiteness).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "core/flex/flex_model.hpp"

namespace crossdyn::flex {

// Limits against hostile input (docs/flexible-data.md): bytes per file, rows (kMaxNodes) and
// modes (kMaxModes, so columns <= 11 + 6 kMaxModes), from flex_model.hpp.
inline constexpr std::size_t kMaxNodalFileBytes = std::size_t{64} << 20;  // 64 MiB

// Reads both files (modes_path empty: no modes file, allowed only when the nodes file has no
// mode columns) and validates them, then validate_flex. Relative paths are the caller's business
// (the scene reader resolves them against the scene file's folder).
FlexModel read_nodal_csv(const std::string& nodes_path, const std::string& modes_path);

// The same from text in memory; the labels stand for the files in messages (an empty
// modes_label means there is no modes file).
FlexModel read_nodal_csv_text(std::string_view nodes_text, const std::string& nodes_label,
                              std::string_view modes_text, const std::string& modes_label);

// A FlexBody as the two files (K and D as matrix columns, every number in its shortest form that
// reads back exactly), so read_nodal_csv_text(write_nodal_csv(f)) gives f back (with its CM
// already at the origin, the shift is zero to rounding).
struct NodalCsv {
  std::string nodes;
  std::string modes;
};
NodalCsv write_nodal_csv(const FlexBody& f);

}  // namespace crossdyn::flex
