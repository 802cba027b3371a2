// Nodal data files (core/flex/nodal_csv.hpp): a strict CSV reader with positions in every
// message, the checks of the format, and the writer.
#include "core/flex/nodal_csv.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <vector>

#include "core/errors.hpp"
#include "core/input_file.hpp"
#include "core/scene/text.hpp"

namespace crossdyn::flex {

namespace {

// x for a message: its shortest round-trip form, -0 as 0.
std::string shown(double x) { return scene::shortest(x == 0 ? 0.0 : x); }

// A field as written, for messages: at most 40 characters, non-printable bytes as '?'.
std::string excerpt(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (s.size() > 40) out += "...";
  return "'" + out + "'";
}

// ---- The CSV layer -------------------------------------------------------------------------

struct Field {
  std::string_view text;  // trimmed
  int column = 0;         // 1-based character position of the field's first character
};
struct Row {
  int line = 0;
  std::vector<Field> fields;
};
struct Table {
  std::string label;
  Row header;
  std::vector<Row> rows;
};

[[noreturn]] void fail_at(const std::string& label, int line, int column, const std::string& what) {
  throw InputError(label + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + what);
}

// Splits `text` into a header and rows. Comment lines (first non-blank character '#') and blank
// lines are skipped; CR before LF is dropped. Control characters (other than tab) are errors
// everywhere; other non-ASCII bytes are accepted in comments only. At most max_rows data rows.
Table parse_csv(std::string_view text, const std::string& label, std::size_t max_rows) {
  Table t;
  t.label = label;
  bool have_header = false;
  int line = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    ++line;
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view s = text.substr(pos, end - pos);
    pos = end + 1;
    if (!s.empty() && s.back() == '\r') s.remove_suffix(1);
    const std::size_t first = s.find_first_not_of(" \t");
    const bool comment = first != std::string_view::npos && s[first] == '#';
    for (std::size_t i = 0; i < s.size(); ++i) {
      const auto c = static_cast<unsigned char>(s[i]);
      if ((c < 0x20 && c != '\t') || c == 0x7f)
        fail_at(label, line, static_cast<int>(i) + 1,
                "control character " + std::to_string(c) + " (only tab is allowed)");
      if (c >= 0x80 && !comment)
        fail_at(label, line, static_cast<int>(i) + 1,
                "non-ASCII character: names are ASCII identifiers and values plain numbers "
                "(non-ASCII text is allowed in '#' comments)");
      if (c == '"' && !comment)
        fail_at(label, line, static_cast<int>(i) + 1,
                "quoted fields are not supported: names are identifiers and values plain numbers");
    }
    if (first == std::string_view::npos || comment) continue;

    Row row;
    row.line = line;
    std::size_t f = 0;
    while (true) {
      std::size_t comma = s.find(',', f);
      if (comma == std::string_view::npos) comma = s.size();
      std::string_view field = s.substr(f, comma - f);
      std::size_t lead = field.find_first_not_of(" \t");
      if (lead == std::string_view::npos) lead = field.size();
      field.remove_prefix(lead);
      while (!field.empty() && (field.back() == ' ' || field.back() == '\t')) field.remove_suffix(1);
      row.fields.push_back({field, static_cast<int>(f + lead) + 1});
      if (comma == s.size()) break;
      f = comma + 1;
    }
    if (!have_header) {
      t.header = std::move(row);
      have_header = true;
      continue;
    }
    if (t.rows.size() >= max_rows)
      fail_at(label, line, 1, "more than " + std::to_string(max_rows) + " rows");
    t.rows.push_back(std::move(row));
  }
  if (!have_header) throw InputError(label + ": no header line (the file is empty or all comments)");
  return t;
}

// Column names of the header, checked to be present, non-empty and unique.
std::vector<std::string_view> header_names(const Table& t) {
  std::vector<std::string_view> names;
  std::map<std::string_view, int> seen;
  for (const Field& f : t.header.fields) {
    if (f.text.empty()) fail_at(t.label, t.header.line, f.column, "empty column name in the header");
    if (const auto it = seen.find(f.text); it != seen.end())
      fail_at(t.label, t.header.line, f.column,
              "duplicate column " + excerpt(f.text) + " (first at column " +
                  std::to_string(it->second) + ")");
    seen.emplace(f.text, f.column);
    names.push_back(f.text);
  }
  return names;
}

// Every data row has exactly the header's number of fields, none empty.
void check_row_shape(const Table& t, const Row& r) {
  const std::size_t n = t.header.fields.size();
  if (r.fields.size() > n)
    fail_at(t.label, r.line, r.fields[n].column,
            "this row has " + std::to_string(r.fields.size()) + " fields, the header " +
                std::to_string(n) + ": extra field " + excerpt(r.fields[n].text));
  if (r.fields.size() < n)
    fail_at(t.label, r.line, r.fields.back().column + static_cast<int>(r.fields.back().text.size()),
            "this row has " + std::to_string(r.fields.size()) + " fields, the header " +
                std::to_string(n) + ": column " + excerpt(t.header.fields[r.fields.size()].text) +
                " is missing");
  for (std::size_t i = 0; i < n; ++i)
    if (r.fields[i].text.empty())
      fail_at(t.label, r.line, r.fields[i].column,
              "column " + excerpt(t.header.fields[i].text) + ": empty value");
}

// A finite number with |x| <= limit, else an error naming the column.
double number(const Table& t, const Row& r, std::size_t col, double limit = 1e12) {
  const Field& f = r.fields[col];
  const std::string column = "column " + excerpt(t.header.fields[col].text) + ": ";
  std::string_view s = f.text;
  if (s.size() > 1 && s.front() == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  double x = 0;
  const auto res = std::from_chars(s.data(), s.data() + s.size(), x);
  if (res.ec == std::errc::result_out_of_range || (res.ec == std::errc() && res.ptr == s.data() + s.size() && !std::isfinite(x)))
    fail_at(t.label, r.line, f.column, column + "non-finite or out-of-range number " + excerpt(f.text));
  if (res.ec != std::errc() || res.ptr != s.data() + s.size())
    fail_at(t.label, r.line, f.column, column + "expected a number, found " + excerpt(f.text));
  if (std::abs(x) > limit)
    fail_at(t.label, r.line, f.column,
            column + "absurd value " + shown(x) + " (magnitude above " + shown(limit) + ")");
  if (x != 0 && std::abs(x) < 1e-100)  // as the scene reader (kTiny): subnormal values make NaN runs
    fail_at(t.label, r.line, f.column,
            column + "value " + shown(x) + " is too small to compute with (a magnitude above 0 "
            "and below 1e-100)");
  return x;
}

// The file's text; never blocks on a special file and never reads more than the limit
// (core/input_file.hpp): a FIFO, device, socket or directory is refused.
std::string read_limited(const std::string& path) {
  InputFile in = read_input_file(path, kMaxNodalFileBytes, Pipes::Refuse);
  if (!in.problem.empty()) throw InputError(path + ": " + in.problem);
  if (in.text.size() > kMaxNodalFileBytes)
    throw InputError(path + ": the file is larger than " +
                     std::to_string(kMaxNodalFileBytes >> 20) + " MiB");
  return std::move(in.text);
}

// ---- The nodes file ------------------------------------------------------------------------

constexpr std::array<std::string_view, 6> kJ = {"Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz"};
constexpr std::array<std::string_view, 6> kComponent = {"ux", "uy", "uz", "rx", "ry", "rz"};

struct NodesLayout {
  std::size_t name = 0, mass = 0;
  std::array<std::size_t, 3> p{};
  std::optional<std::array<std::size_t, 6>> J;
  std::vector<std::string> modes;                    // in header order
  std::vector<std::array<std::size_t, 6>> mode_cols;  // ux uy uz rx ry rz per mode
};

NodesLayout nodes_layout(const Table& t) {
  const std::vector<std::string_view> names = header_names(t);
  const int hl = t.header.line;
  const auto col_of = [&](std::size_t i) { return t.header.fields[i].column; };
  constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  NodesLayout L;
  std::size_t name = kNone, mass = kNone;
  std::array<std::size_t, 3> p{kNone, kNone, kNone};
  std::array<std::size_t, 6> J{kNone, kNone, kNone, kNone, kNone, kNone};
  std::map<std::string, std::size_t> mode_index;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const std::string_view c = names[i];
    if (c == "name") { name = i; continue; }
    if (c == "mass") { mass = i; continue; }
    if (c == "x" || c == "y" || c == "z") { p[static_cast<std::size_t>(c[0] - 'x')] = i; continue; }
    if (const auto j = std::find(kJ.begin(), kJ.end(), c); j != kJ.end()) {
      J[static_cast<std::size_t>(j - kJ.begin())] = i;
      continue;
    }
    const std::size_t dot = c.find('.');
    if (dot == std::string_view::npos)
      fail_at(t.label, hl, col_of(i),
              "unknown column " + excerpt(c) +
                  ": expected name, mass, x, y, z, Jxx, Jyy, Jzz, Jxy, Jxz, Jyz or "
                  "<mode>.ux/uy/uz/rx/ry/rz");
    const std::string mode(c.substr(0, dot));
    const std::string_view comp = c.substr(dot + 1);
    if (auto p_ = mode_name_problem(mode)) fail_at(t.label, hl, col_of(i), "column " + excerpt(c) + ": " + *p_);
    const auto k = std::find(kComponent.begin(), kComponent.end(), comp);
    if (k == kComponent.end())
      fail_at(t.label, hl, col_of(i),
              "column " + excerpt(c) + ": unknown component " + excerpt(comp) + " of mode '" + mode +
                  "': expected ux, uy, uz (shape) or rx, ry, rz (slope)");
    auto [it, added] = mode_index.emplace(mode, L.modes.size());
    if (added) {
      if (L.modes.size() >= static_cast<std::size_t>(kMaxModes))
        fail_at(t.label, hl, col_of(i),
                "more than " + std::to_string(kMaxModes) + " modes (column " + excerpt(c) + ")");
      L.modes.push_back(mode);
      L.mode_cols.push_back({kNone, kNone, kNone, kNone, kNone, kNone});
    }
    L.mode_cols[it->second][static_cast<std::size_t>(k - kComponent.begin())] = i;
  }
  const int end_col = t.header.fields.back().column + static_cast<int>(t.header.fields.back().text.size());
  const auto missing = [&](std::string_view what) {
    fail_at(t.label, hl, end_col, "missing column '" + std::string(what) + "'");
  };
  if (name == kNone) missing("name");
  if (mass == kNone) missing("mass");
  for (std::size_t a = 0; a < 3; ++a)
    if (p[a] == kNone) missing(std::string(1, static_cast<char>('x' + a)));
  const auto given = std::count_if(J.begin(), J.end(), [&](std::size_t c) { return c != kNone; });
  if (given != 0 && given != 6) {
    std::size_t have = 0, lack = 0;
    for (std::size_t j = 0; j < 6; ++j) (J[j] != kNone ? have : lack) = j;
    fail_at(t.label, hl, col_of(J[have]),
            "column '" + std::string(kJ[have]) + "' without '" + std::string(kJ[lack]) +
                "': give all six J columns (Jxx, Jyy, Jzz, Jxy, Jxz, Jyz) or none");
  }
  for (std::size_t m = 0; m < L.modes.size(); ++m)
    for (std::size_t k = 0; k < 6; ++k)
      if (L.mode_cols[m][k] == kNone)
        fail_at(t.label, hl, end_col,
                "mode '" + L.modes[m] + "' has no column '" + L.modes[m] + "." +
                    std::string(kComponent[k]) +
                    "': give ux, uy, uz (shape) and rx, ry, rz (slope) for every mode");
  L.name = name;
  L.mass = mass;
  L.p = p;
  if (given == 6) L.J = J;
  return L;
}

FlexBody read_nodes(const Table& t, const NodesLayout& L) {
  FlexBody f;
  f.mode_names = L.modes;
  const int n = static_cast<int>(L.modes.size());
  std::map<std::string_view, int> lines;
  double total = 0;
  for (const Row& r : t.rows) {
    check_row_shape(t, r);
    FlexNode node;
    const Field& nf = r.fields[L.name];
    if (auto p = name_problem(nf.text)) fail_at(t.label, r.line, nf.column, "column 'name': " + *p);
    if (const auto it = lines.find(nf.text); it != lines.end())
      fail_at(t.label, r.line, nf.column,
              "column 'name': duplicate node name " + excerpt(nf.text) + " (first on line " +
                  std::to_string(it->second) + ")");
    lines.emplace(nf.text, r.line);
    node.name = std::string(nf.text);
    node.mass = number(t, r, L.mass);
    if (node.mass < 0)
      fail_at(t.label, r.line, r.fields[L.mass].column,
              "column 'mass': negative mass " + shown(node.mass) + " kg (a node's mass is >= 0)");
    total += node.mass;
    for (int a = 0; a < 3; ++a) node.p_BoNi_B(a) = number(t, r, L.p[static_cast<std::size_t>(a)]);
    if (L.J) {
      const auto& J = *L.J;
      std::array<double, 6> v{};
      for (std::size_t j = 0; j < 6; ++j) v[j] = number(t, r, J[j]);
      node.J_Ni_B << v[0], v[3], v[4], v[3], v[1], v[5], v[4], v[5], v[2];
      if (auto p = inertia_problem(node.J_Ni_B))
        fail_at(t.label, r.line, r.fields[J[0]].column, "columns Jxx ... Jyz of node '" + node.name + "': " + *p);
    }
    node.Phi_B.resize(3, n);
    node.Psi_B.resize(3, n);
    for (int m = 0; m < n; ++m)
      for (int k = 0; k < 3; ++k) {
        node.Phi_B(k, m) = number(t, r, L.mode_cols[static_cast<std::size_t>(m)][static_cast<std::size_t>(k)]);
        node.Psi_B(k, m) = number(t, r, L.mode_cols[static_cast<std::size_t>(m)][static_cast<std::size_t>(k + 3)]);
      }
    f.nodes.push_back(std::move(node));
  }
  if (f.nodes.empty()) throw InputError(t.label + ": no nodes (the file has a header but no rows)");
  if (!(total > 0))
    throw InputError(t.label + ": the nodes' total mass is zero: at least one node needs mass");
  return f;
}

// ---- The modes file ------------------------------------------------------------------------

void read_modes(const Table& t, FlexBody& f) {
  const std::vector<std::string_view> names = header_names(t);
  const int hl = t.header.line;
  const int n = f.modes();
  constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  std::size_t mode = kNone, freq = kNone, ratio = kNone;
  std::vector<std::size_t> Kc(static_cast<std::size_t>(n), kNone), Dc(Kc);
  std::size_t nK = 0, nD = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const std::string_view c = names[i];
    const int col = t.header.fields[i].column;
    if (c == "mode") { mode = i; continue; }
    if (c == "frequency_hz") { freq = i; continue; }
    if (c == "damping_ratio") { ratio = i; continue; }
    if (c.size() > 2 && (c[0] == 'K' || c[0] == 'D') && c[1] == '.') {
      const std::string m(c.substr(2));
      const auto it = std::find(f.mode_names.begin(), f.mode_names.end(), m);
      if (it == f.mode_names.end())
        fail_at(t.label, hl, col,
                "column " + excerpt(c) + ": '" + m + "' is not a mode of the nodes file");
      const auto k = static_cast<std::size_t>(it - f.mode_names.begin());
      (c[0] == 'K' ? Kc : Dc)[k] = i;
      ++(c[0] == 'K' ? nK : nD);
      continue;
    }
    fail_at(t.label, hl, col,
            "unknown column " + excerpt(c) +
                ": expected mode, frequency_hz, damping_ratio, K.<mode> or D.<mode>");
  }
  const int end_col = t.header.fields.back().column + static_cast<int>(t.header.fields.back().text.size());
  if (mode == kNone) fail_at(t.label, hl, end_col, "missing column 'mode'");
  const auto need_all = [&](const std::vector<std::size_t>& cols, std::size_t count, char which) {
    if (count == 0 || count == static_cast<std::size_t>(n)) return;
    for (std::size_t k = 0; k < cols.size(); ++k)
      if (cols[k] == kNone)
        fail_at(t.label, hl, end_col,
                std::string("missing column '") + which + "." + f.mode_names[k] + "': give " + which +
                    ".<mode> for every mode (a full row of " + which + ") or none");
  };
  need_all(Kc, nK, 'K');
  need_all(Dc, nD, 'D');
  if (freq != kNone && nK > 0)
    fail_at(t.label, hl, t.header.fields[freq].column,
            "column 'frequency_hz' and K.<mode> columns: give K either as frequencies or as a matrix");
  if (n > 0 && freq == kNone && nK == 0)
    fail_at(t.label, hl, end_col, "no stiffness: give the column frequency_hz or the columns K.<mode>");
  if (ratio != kNone && freq == kNone)
    fail_at(t.label, hl, t.header.fields[ratio].column,
            "column 'damping_ratio' goes with 'frequency_hz'; with K.<mode> columns give D.<mode>");
  if (ratio != kNone && nD > 0)
    fail_at(t.label, hl, t.header.fields[ratio].column,
            "column 'damping_ratio' and D.<mode> columns: give the damping one way");

  f.K = Eigen::MatrixXd::Zero(n, n);
  f.D = Eigen::MatrixXd::Zero(n, n);
  // Where each K and D entry was read, for the symmetry message.
  std::vector<std::pair<int, int>> where_K(static_cast<std::size_t>(n * n)), where_D(where_K);
  if (t.rows.size() > static_cast<std::size_t>(n)) {
    const Row& r = t.rows[static_cast<std::size_t>(n)];
    fail_at(t.label, r.line, r.fields.front().column,
            "more rows than the nodes file's " + std::to_string(n) + " modes");
  }
  for (std::size_t k = 0; k < t.rows.size(); ++k) {
    const Row& r = t.rows[k];
    check_row_shape(t, r);
    const Field& mf = r.fields[mode];
    if (mf.text != f.mode_names[k])
      fail_at(t.label, r.line, mf.column,
              "column 'mode': " + excerpt(mf.text) + " but the nodes file's mode " +
                  std::to_string(k + 1) + " is '" + f.mode_names[k] +
                  "' (one row per mode, in the nodes file's order)");
    double M_k = 0;
    for (const FlexNode& node : f.nodes) M_k += node.mass * node.Phi_B.col(static_cast<Eigen::Index>(k)).squaredNorm();
    const auto ki = static_cast<Eigen::Index>(k);
    if (freq != kNone) {
      const double fr = number(t, r, freq);
      if (fr < 0)
        fail_at(t.label, r.line, r.fields[freq].column,
                "column 'frequency_hz': negative frequency " + shown(fr) + " Hz");
      const double omega = 2 * std::numbers::pi * fr;
      f.K(ki, ki) = omega * omega * M_k;
      // The stiffness made from the frequency holds the bound a K.<mode> column holds (1e18), so
      // the body reads back from the files crossdyn writes (found by nodal_csv_fuzzer: a mode
      // shape of 1e11 made K = 3.6e27 from 8.7 Hz).
      if (!(f.K(ki, ki) <= 1e18))
        fail_at(t.label, r.line, r.fields[freq].column,
                "column 'frequency_hz': " + shown(fr) + " Hz with the mode's modal mass " +
                    shown(M_k) + " kg gives the stiffness (2 pi f)^2 M = " + shown(f.K(ki, ki)) +
                    ", above 1e18: check the mode shape's scale in the nodes file");
      if (ratio != kNone) {
        const double z = number(t, r, ratio);
        if (z < 0)
          fail_at(t.label, r.line, r.fields[ratio].column,
                  "column 'damping_ratio': negative damping ratio " + shown(z));
        f.D(ki, ki) = 2 * z * omega * M_k;
        if (!(f.D(ki, ki) <= 1e18))
          fail_at(t.label, r.line, r.fields[ratio].column,
                  "column 'damping_ratio': " + shown(z) + " gives the damping 2 zeta (2 pi f) M = " +
                      shown(f.D(ki, ki)) + ", above 1e18: check the mode shape's scale in the nodes file");
      }
    }
    for (Eigen::Index j = 0; j < n; ++j) {
      const auto ju = static_cast<std::size_t>(j);
      if (nK > 0) {
        f.K(ki, j) = number(t, r, Kc[ju], 1e18);
        where_K[k * static_cast<std::size_t>(n) + ju] = {r.line, r.fields[Kc[ju]].column};
      }
      if (nD > 0) {
        f.D(ki, j) = number(t, r, Dc[ju], 1e18);
        where_D[k * static_cast<std::size_t>(n) + ju] = {r.line, r.fields[Dc[ju]].column};
      }
    }
  }
  if (t.rows.size() < static_cast<std::size_t>(n))
    throw InputError(t.label + ": " + std::to_string(t.rows.size()) + " rows for the nodes file's " +
                     std::to_string(n) + " modes: mode '" + f.mode_names[t.rows.size()] +
                     "' has no row");
  // Symmetry, at the later of the two entries.
  const auto symmetric = [&](const Eigen::MatrixXd& A, const std::vector<std::pair<int, int>>& where,
                             char which) {
    const double tol = 1e-9 * A.cwiseAbs().maxCoeff();
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < i; ++j)
        if (std::abs(A(i, j) - A(j, i)) > tol) {
          const auto [line, col] = where[static_cast<std::size_t>(i * n + j)];
          const auto [line0, col0] = where[static_cast<std::size_t>(j * n + i)];
          (void)col0;
          const std::string a = f.mode_names[static_cast<std::size_t>(i)], b = f.mode_names[static_cast<std::size_t>(j)];
          fail_at(t.label, line, col,
                  std::string("column '") + which + "." + b + "': " + which + "(" + a + ", " + b +
                      ") = " + shown(A(i, j)) + " differs from " + which + "(" + b + ", " + a +
                      ") = " + shown(A(j, i)) + " (line " + std::to_string(line0) + "): " + which +
                      " must be symmetric");
        }
  };
  if (nK > 0) symmetric(f.K, where_K, 'K');
  if (nD > 0) symmetric(f.D, where_D, 'D');
  if (auto p = modal_matrix_problem(f.K, f, "K")) throw InputError(t.label + ": " + *p);
  if (auto p = modal_matrix_problem(f.D, f, "D")) throw InputError(t.label + ": " + *p);
}

}  // namespace

FlexModel read_nodal_csv_text(std::string_view nodes_text, const std::string& nodes_label,
                              std::string_view modes_text, const std::string& modes_label) {
  if (nodes_text.size() > kMaxNodalFileBytes)
    throw InputError(nodes_label + ": the file is larger than " + std::to_string(kMaxNodalFileBytes >> 20) + " MiB");
  if (modes_text.size() > kMaxNodalFileBytes)
    throw InputError(modes_label + ": the file is larger than " + std::to_string(kMaxNodalFileBytes >> 20) + " MiB");
  const Table nodes = parse_csv(nodes_text, nodes_label, kMaxNodes);
  const NodesLayout layout = nodes_layout(nodes);
  FlexModel out;
  out.flex = read_nodes(nodes, layout);
  FlexBody& f = out.flex;
  if (modes_label.empty()) {
    if (f.modes() > 0)
      throw InputError(nodes_label + ": the file has " + std::to_string(f.modes()) +
                       " modes but no modes file gives their stiffness");
    f.K.resize(0, 0);
    f.D.resize(0, 0);
  } else {
    read_modes(parse_csv(modes_text, modes_label, static_cast<std::size_t>(kMaxModes)), f);
  }

  // Shift to the nodes' CM (p_BoNi_B = p_RoNi_R - p_RoBo_R).
  const RigidProperties about_R = rigid_properties(f);
  Eigen::Vector3d first_moment = Eigen::Vector3d::Zero();
  for (const FlexNode& node : f.nodes) first_moment += node.mass * node.p_BoNi_B;
  out.p_RoBo_R = first_moment / about_R.mass;
  for (FlexNode& node : f.nodes) node.p_BoNi_B -= out.p_RoBo_R;
  f.origin = "nodal data: " + nodes_label + (modes_label.empty() ? "" : ", " + modes_label);

  const RigidProperties r = rigid_properties(f);
  out.mass = r.mass;
  out.I_BBo_B = r.I;
  validate_flex(f, nodes_label);
  return out;
}

FlexModel read_nodal_csv(const std::string& nodes_path, const std::string& modes_path) {
  const std::string nodes = read_limited(nodes_path);
  const std::string modes = modes_path.empty() ? std::string() : read_limited(modes_path);
  return read_nodal_csv_text(nodes, nodes_path, modes, modes_path);
}

NodalCsv write_nodal_csv(const FlexBody& f) {
  std::string origin;
  for (char c : f.origin) origin += (c >= 0x20 && c < 0x7f) ? c : '?';
  NodalCsv out;
  std::string& s = out.nodes;
  s += "# crossdyn nodal data, one row per node (docs/flexible-data.md). SI units.\n";
  s += "# from " + origin + "\n";
  s += "name,mass,x,y,z,Jxx,Jyy,Jzz,Jxy,Jxz,Jyz";
  for (const std::string& m : f.mode_names)
    for (std::string_view c : kComponent) s += "," + m + "." + std::string(c);
  s += "\n";
  for (const FlexNode& node : f.nodes) {
    s += node.name + "," + shown(node.mass);
    for (int a = 0; a < 3; ++a) s += "," + shown(node.p_BoNi_B(a));
    const Eigen::Matrix3d& J = node.J_Ni_B;
    for (double v : {J(0, 0), J(1, 1), J(2, 2), J(0, 1), J(0, 2), J(1, 2)}) s += "," + shown(v);
    for (int m = 0; m < f.modes(); ++m) {
      for (int k = 0; k < 3; ++k) s += "," + shown(node.Phi_B(k, m));
      for (int k = 0; k < 3; ++k) s += "," + shown(node.Psi_B(k, m));
    }
    s += "\n";
  }
  std::string& d = out.modes;
  d += "# crossdyn modal stiffness K and damping D, one row per mode (docs/flexible-data.md)\n";
  d += "mode";
  for (const std::string& m : f.mode_names) d += ",K." + m;
  for (const std::string& m : f.mode_names) d += ",D." + m;
  d += "\n";
  for (int i = 0; i < f.modes(); ++i) {
    d += f.mode_names[static_cast<std::size_t>(i)];
    for (int j = 0; j < f.modes(); ++j) d += "," + shown(f.K(i, j));
    for (int j = 0; j < f.modes(); ++j) d += "," + shown(f.D(i, j));
    d += "\n";
  }
  return out;
}

}  // namespace crossdyn::flex
