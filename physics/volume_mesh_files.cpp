#include "physics/volume_mesh_files.hpp"
#include "physics/detail/messages.hpp"

#include <expat.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <unordered_map>

namespace lumen::physics {
namespace {

using detail::fail;  // "<file>: <where>: <problem>"

// Whitespace-separated tokens of a text, each with the line it is on; every read names the file, the line and
// what was expected.
class Tokens {
 public:
  Tokens(const std::string& text, std::string file, std::string context, int first_line = 1)
      : text_(text), file_(std::move(file)), context_(std::move(context)), line_(first_line), token_line_(first_line) {}

  bool done() {
    skip_space();
    return pos_ >= text_.size();
  }
  std::string_view next(const std::string& what) {
    if (done()) fail(file_, "line " + std::to_string(line_), "the file ends inside " + context_ + " (expected " + what + ")");
    const size_t start = pos_;
    token_line_ = line_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    return std::string_view(text_).substr(start, pos_ - start);
  }
  long integer(const std::string& what) {
    const std::string_view t = next(what);
    long v = 0;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size()) bad(what, t);
    return v;
  }
  // A count or index: an integer in [0, hi].
  long count(const std::string& what, long hi = INT_MAX) {
    const long v = integer(what);
    if (v < 0 || v > hi) fail(file_, where(), what + " out of range [0, " + std::to_string(hi) + "] (value " + std::to_string(v) + ")");
    return v;
  }
  // A count of items of `tokens` tokens each that the rest of the text can hold (each token and its separator
  // take at least 2 characters), so that a corrupt count is refused before anything is allocated for it.
  long items(const std::string& what, long tokens) {
    const long v = count(what);
    if (v > static_cast<long>((text_.size() - pos_) / 2 + 1) / tokens)
      fail(file_, where(), what + " " + std::to_string(v) + " is more than the rest of the file holds (truncated?)");
    return v;
  }
  double real(const std::string& what) {
    const std::string_view t = next(what);
    double v = 0;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size() || !std::isfinite(v)) bad(what, t);
    return v;
  }
  // The next token, which must be `word`.
  void expect(const std::string& word) {
    const std::string_view t = next(word);
    if (t != word) fail(file_, where(), "expected " + word + " in " + context_ + " (got \"" + std::string(t) + "\")");
  }
  // A double-quoted string (may hold spaces), quotes removed.
  std::string quoted(const std::string& what) {
    std::string s(next(what));
    while (s.size() < 2 || s.front() != '"' || s.back() != '"') {
      if (s.front() != '"') bad(what, s);
      s += " " + std::string(next(what));
    }
    return s.substr(1, s.size() - 2);
  }
  // The rest of the current line (the cursor then at the next line's start).
  std::string line_text() {
    const size_t start = pos_;
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    std::string s = text_.substr(start, pos_ - start);
    if (pos_ < text_.size()) ++pos_, ++line_;
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
    return s;
  }
  void set_context(std::string c) { context_ = std::move(c); }
  // The line of the last token read.
  std::string where() const { return "line " + std::to_string(token_line_); }
  const std::string& file() const { return file_; }
  int line() const { return line_; }

 private:
  void skip_space() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }
  [[noreturn]] void bad(const std::string& what, std::string_view t) const {
    fail(file_, where(), "expected " + what + " in " + context_ + " (got \"" + std::string(t) + "\")");
  }

  const std::string& text_;
  std::string file_, context_;
  size_t pos_ = 0;
  int line_, token_line_ = 0;
};

// What an element of the file is to the reader: kept (a tet, a triangle), refused (other volume elements), or
// ignored (points, lines, other faces).
enum class Role { kTet, kTriangle, kTet10, kOtherVolume, kIgnored };

// One element type of a format: its number, node count, role and name.
struct CellType {
  int type;
  int nodes;  // 0: any (polyhedra, Lagrange cells)
  Role role;
  const char* name;
};

// gmsh element types (gmsh reference manual, "MSH file format": elm-type). Node order of type 4 is gmsh's
// reference tet (0,0,0), (1,0,0), (0,1,0), (0,0,1): positive, Lumen's, so it is kept as it is.
constexpr CellType kGmshTypes[] = {
    {1, 2, Role::kIgnored, "line"},        {2, 3, Role::kTriangle, "triangle"},
    {3, 4, Role::kIgnored, "quadrangle"},  {4, 4, Role::kTet, "tetrahedron"},
    {5, 8, Role::kOtherVolume, "hexahedron"}, {6, 6, Role::kOtherVolume, "prism"},
    {7, 5, Role::kOtherVolume, "pyramid"}, {8, 3, Role::kIgnored, "3-node line"},
    {9, 6, Role::kIgnored, "6-node triangle"}, {10, 9, Role::kIgnored, "9-node quadrangle"},
    {11, 10, Role::kTet10, "10-node tetrahedron"}, {12, 27, Role::kOtherVolume, "27-node hexahedron"},
    {13, 18, Role::kOtherVolume, "18-node prism"}, {14, 14, Role::kOtherVolume, "14-node pyramid"},
    {15, 1, Role::kIgnored, "point"},      {16, 8, Role::kIgnored, "8-node quadrangle"},
    {17, 20, Role::kOtherVolume, "20-node hexahedron"}, {18, 15, Role::kOtherVolume, "15-node prism"},
    {19, 13, Role::kOtherVolume, "13-node pyramid"}};

// VTK cell types (vtkCellType.h). VTK_TETRA's points 0, 1, 2 make a triangle whose right-hand normal points
// toward point 3: positive, Lumen's order, kept as it is.
constexpr CellType kVtkTypes[] = {
    {1, 1, Role::kIgnored, "vertex"},       {2, 0, Role::kIgnored, "poly-vertex"},
    {3, 2, Role::kIgnored, "line"},         {4, 0, Role::kIgnored, "poly-line"},
    {5, 3, Role::kTriangle, "triangle"},    {6, 0, Role::kIgnored, "triangle strip"},
    {7, 0, Role::kIgnored, "polygon"},      {8, 4, Role::kIgnored, "pixel"},
    {9, 4, Role::kIgnored, "quad"},         {10, 4, Role::kTet, "tetra"},
    {11, 8, Role::kOtherVolume, "voxel"},   {12, 8, Role::kOtherVolume, "hexahedron"},
    {13, 6, Role::kOtherVolume, "wedge"},   {14, 5, Role::kOtherVolume, "pyramid"},
    {15, 10, Role::kOtherVolume, "pentagonal prism"}, {16, 12, Role::kOtherVolume, "hexagonal prism"},
    {21, 3, Role::kIgnored, "quadratic edge"}, {22, 6, Role::kIgnored, "quadratic triangle"},
    {23, 8, Role::kIgnored, "quadratic quad"}, {24, 10, Role::kTet10, "quadratic tetra"},
    {25, 20, Role::kOtherVolume, "quadratic hexahedron"}, {26, 15, Role::kOtherVolume, "quadratic wedge"},
    {27, 13, Role::kOtherVolume, "quadratic pyramid"}, {42, 0, Role::kOtherVolume, "polyhedron"},
    {71, 0, Role::kOtherVolume, "Lagrange tetrahedron"}, {72, 0, Role::kOtherVolume, "Lagrange hexahedron"}};

template <size_t N>
const CellType* find_type(const CellType (&types)[N], long type) {
  for (const CellType& t : types)
    if (t.type == type) return &t;
  return nullptr;
}

// The file's contents as they are read: elements kept in order, node ids mapped to rows.
struct Collector {
  VolumeMeshFile& out;
  const char* format;  // "gmsh" | "VTK", for messages
  std::vector<std::array<double, 3>> nodes;
  std::unordered_map<long, int> row_of;  // node id -> row (gmsh); VTK uses the index itself
  std::vector<std::array<int, 4>> tets;
  std::vector<std::array<int, 3>> tris;
  long elements = 0;

  void node(long id, const std::array<double, 3>& x, const std::string& where) {
    if (!row_of.emplace(id, static_cast<int>(nodes.size())).second)
      fail(out.file, where, "node id " + std::to_string(id) + " is defined twice");
    nodes.push_back(x);
  }
  int row(long id, const std::string& where) const {
    const auto it = row_of.find(id);
    if (it == row_of.end()) fail(out.file, where, "node id " + std::to_string(id) + " is used but not defined");
    return it->second;
  }
  // One element: a tet or triangle kept (tag: the triangle's), another volume element refused, the rest ignored.
  void element(const CellType& t, long id, const std::vector<long>& node_ids, int tag, const std::string& where) {
    ++elements;
    const std::string kind = std::string("a ") + t.name + " (" + format + " type " + std::to_string(t.type) + ")";
    if (t.role == Role::kTet10)
      fail(out.file, where, kind + ": only linear tetrahedra are supported; export the mesh with linear (4-node) tets");
    if (t.role == Role::kOtherVolume) fail(out.file, where, kind + ": only linear tetrahedra are supported");
    if (t.role == Role::kIgnored) return;
    if (t.nodes != static_cast<int>(node_ids.size()))
      fail(out.file, where, kind + " with " + std::to_string(node_ids.size()) + " nodes");
    if (t.role == Role::kTet) {
      tets.push_back({row(node_ids[0], where), row(node_ids[1], where), row(node_ids[2], where), row(node_ids[3], where)});
      out.tet_ids.push_back(id);
    } else {
      tris.push_back({row(node_ids[0], where), row(node_ids[1], where), row(node_ids[2], where)});
      out.triangle_tags.push_back(tag);
    }
  }
  // Moves what was read into `out`; refuses a file without tets.
  void finish() {
    if (tets.empty())
      fail(out.file, "elements", "no tetrahedra (" + std::to_string(nodes.size()) + " nodes, " +
                                     std::to_string(elements) + " elements, none a linear tetrahedron)");
    out.nodes.resize(static_cast<Eigen::Index>(nodes.size()), 3);
    for (size_t i = 0; i < nodes.size(); ++i)
      for (int k = 0; k < 3; ++k) out.nodes(static_cast<Eigen::Index>(i), k) = nodes[i][k];
    out.tets.resize(static_cast<Eigen::Index>(tets.size()), 4);
    for (size_t i = 0; i < tets.size(); ++i)
      for (int k = 0; k < 4; ++k) out.tets(static_cast<Eigen::Index>(i), k) = tets[i][k];
    out.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
    for (size_t i = 0; i < tris.size(); ++i)
      for (int k = 0; k < 3; ++k) out.triangles(static_cast<Eigen::Index>(i), k) = tris[i][k];
  }
};

// ---------------------------------------------------------------------------------------------------------------
// gmsh

// gmsh file format versions read: 2.x (2.2's layout) and 4.1.
enum class GmshVersion { kV2, kV41 };

std::array<double, 3> read_xyz(Tokens& t) {
  return {t.real("x coordinate"), t.real("y coordinate"), t.real("z coordinate")};
}

// $PhysicalNames: "dim tag "name"" lines; the surfaces' (dim 2) are kept.
void read_physical_names(Tokens& t, VolumeMeshFile& out) {
  const long n = t.count("number of physical names");
  for (long i = 0; i < n; ++i) {
    const long dim = t.integer("physical dimension");
    const long tag = t.integer("physical tag");
    std::string name = t.quoted("quoted physical name");
    if (dim == 2) out.tag_names.push_back({std::move(name), static_cast<int>(tag)});
  }
}

// v4.1 $Entities: the first physical tag of each surface entity (those without one are left out).
std::map<long, int> read_entities(Tokens& t) {
  std::array<long, 4> n{};
  for (long& c : n) c = t.count("number of entities");
  std::map<long, int> surface_tag;
  for (int dim = 0; dim < 4; ++dim)
    for (long e = 0; e < n[dim]; ++e) {
      const long tag = t.integer("entity tag");
      for (int k = 0; k < (dim == 0 ? 3 : 6); ++k) t.real("entity bounding box");
      const long phys = t.count("number of physical tags");
      for (long p = 0; p < phys; ++p) {
        const long ptag = t.integer("physical tag");
        if (dim == 2 && p == 0) surface_tag[tag] = static_cast<int>(ptag);
      }
      if (dim > 0)
        for (long b = t.count("number of bounding entities"); b > 0; --b) t.integer("bounding entity tag");
    }
  return surface_tag;
}

// A v4.1 $Nodes / $Elements header "numEntityBlocks num<what>s min<what>Tag max<what>Tag": the number of blocks.
long read_block_header(Tokens& t, const std::string& what) {
  const long blocks = t.count("number of " + what + " blocks");
  t.count("number of " + what + "s");
  t.integer("minimum " + what + " tag");
  t.integer("maximum " + what + " tag");
  return blocks;
}

void read_gmsh_nodes(Tokens& t, GmshVersion v, Collector& c) {
  if (v == GmshVersion::kV2) {
    for (long n = t.count("number of nodes"); n > 0; --n) {
      const long id = t.integer("node id");
      c.node(id, read_xyz(t), t.where());
    }
    return;
  }
  for (long b = read_block_header(t, "node"); b > 0; --b) {
    const long dim = t.count("entity dimension", 3);
    t.integer("entity tag");
    const long parametric = t.count("parametric flag", 1);
    const long n = t.items("number of nodes in block", 4);
    std::vector<long> ids(static_cast<size_t>(n));
    for (long& id : ids) id = t.integer("node tag");
    for (long id : ids) {
      c.node(id, read_xyz(t), t.where());
      for (long p = 0; p < parametric * dim; ++p) t.real("parametric coordinate");
    }
  }
}

void read_gmsh_elements(Tokens& t, GmshVersion v, const std::map<long, int>& surface_tag, Collector& c,
                        const std::string& file) {
  std::vector<long> ids;
  auto element = [&](long type, long id, int tag) {
    const std::string where = t.where() + ", element id " + std::to_string(id);
    const CellType* ct = find_type(kGmshTypes, type);
    if (!ct) fail(file, where, "unsupported gmsh element type " + std::to_string(type));
    ids.resize(static_cast<size_t>(ct->nodes));
    for (long& n : ids) n = t.integer("element node id");
    c.element(*ct, id, ids, tag, where);
  };
  if (v == GmshVersion::kV2) {
    for (long n = t.count("number of elements"); n > 0; --n) {
      const long id = t.integer("element id");
      const long type = t.integer("element type");
      const long ntags = t.count("number of tags");
      int tag = kNoTag;
      for (long k = 0; k < ntags; ++k) {
        const long value = t.integer("element tag");
        if (k == 0) tag = static_cast<int>(value);
      }
      element(type, id, tag);
    }
    return;
  }
  for (long b = read_block_header(t, "element"); b > 0; --b) {
    const long dim = t.count("entity dimension", 3);
    const long entity = t.integer("entity tag");
    const long type = t.integer("element type");
    const auto it = surface_tag.find(entity);
    const int tag = dim == 2 && it != surface_tag.end() ? it->second : kNoTag;
    for (long n = t.count("number of elements in block"); n > 0; --n) element(type, t.integer("element tag"), tag);
  }
}

// $MeshFormat: "version file-type data-size"; binary files and versions other than 2.x and 4.1 refused.
GmshVersion read_mesh_format(Tokens& t, const std::string& file) {
  t.expect("$MeshFormat");
  const std::string version(t.next("version"));
  const std::string where = t.where();
  const long binary = t.integer("file type (0 ASCII, 1 binary)");
  t.integer("data size");
  if (binary != 0)
    fail(file, where, "binary gmsh file: only ASCII .msh files are supported (save with \"-format msh22\" or msh41, not binary)");
  if (version.rfind("2.", 0) == 0 || version == "2") return GmshVersion::kV2;
  if (version == "4.1") return GmshVersion::kV41;
  fail(file, where, "unsupported gmsh format version " + version + " (supported: 2.2 and 4.1)");
}

void parse_gmsh(const std::string& text, Collector& c) {
  const std::string& file = c.out.file;
  Tokens t(text, file, "$MeshFormat");
  const GmshVersion v = read_mesh_format(t, file);
  t.expect("$EndMeshFormat");
  std::map<long, int> surface_tag;
  bool have_nodes = false, have_elements = false;
  while (!t.done()) {
    const std::string section(t.next("a section"));
    const std::string where = t.where();
    if (section.empty() || section[0] != '$') fail(file, where, "expected a section ($Name), got \"" + section + "\"");
    const std::string name = section.substr(1);
    t.set_context(section + " (from " + where + ")");
    if (name == "PhysicalNames") {
      read_physical_names(t, c.out);
    } else if (name == "Entities" && v == GmshVersion::kV41) {
      surface_tag = read_entities(t);
    } else if (name == "Nodes") {
      read_gmsh_nodes(t, v, c);
      have_nodes = true;
    } else if (name == "Elements") {
      if (!have_nodes) fail(file, where, "$Elements before $Nodes");
      read_gmsh_elements(t, v, surface_tag, c, file);
      have_elements = true;
    } else {
      // A section the reader does not need: skipped to its end.
      while (t.next("$End" + name) != "$End" + name) {
      }
      continue;
    }
    t.expect("$End" + name);
  }
  if (!have_nodes || !have_elements)
    fail(file, "line " + std::to_string(t.line()), std::string("no ") + (have_nodes ? "$Elements" : "$Nodes") + " section");
}

// ---------------------------------------------------------------------------------------------------------------
// VTK (shared by the legacy and XML readers)

// The cell-data array whose values are the triangles' tags: "gmsh:physical" (what gmsh and meshio write), else
// the only one-component cell-data array; null when there is none.
const std::vector<long>* tag_array(const std::map<std::string, std::vector<long>>& cell_data) {
  const auto physical = cell_data.find("gmsh:physical");
  if (physical != cell_data.end()) return &physical->second;
  return cell_data.size() == 1 ? &cell_data.begin()->second : nullptr;
}

// The cells of an unstructured grid: cell i has types[i] and points conn[offsets[i] .. offsets[i + 1]).
void add_vtk_cells(const std::vector<long>& types, const std::vector<long>& offsets, const std::vector<long>& conn,
                   const std::vector<long>* tags, Collector& c) {
  std::vector<long> ids;
  for (size_t i = 0; i < types.size(); ++i) {
    const std::string where = "cell " + std::to_string(i);
    const CellType* ct = find_type(kVtkTypes, types[i]);
    if (!ct) fail(c.out.file, where, "unsupported VTK cell type " + std::to_string(types[i]));
    if (offsets[i] < 0 || offsets[i] > offsets[i + 1] || offsets[i + 1] > static_cast<long>(conn.size()))
      fail(c.out.file, where, "cell offsets out of order or past the connectivity (" + std::to_string(conn.size()) + " entries)");
    ids.assign(conn.begin() + offsets[i], conn.begin() + offsets[i + 1]);
    const int tag = tags ? static_cast<int>((*tags)[i]) : kNoTag;
    c.element(*ct, static_cast<long>(i), ids, tag, where);
  }
}

// Point rows of a VTK file: index i is node id i.
void add_vtk_points(const std::vector<double>& xyz, Collector& c) {
  for (size_t i = 0; i + 2 < xyz.size(); i += 3) c.node(static_cast<long>(i / 3), {xyz[i], xyz[i + 1], xyz[i + 2]}, "points");
}

// ---------------------------------------------------------------------------------------------------------------
// VTK legacy (.vtk)

// One data attribute of a legacy file's POINT_DATA / CELL_DATA with n tuples: its integer values kept when it is
// cell data with one component (a tag array candidate), the rest read past.
void read_legacy_attribute(Tokens& t, const std::string& kind, long n, bool cells,
                           std::map<std::string, std::vector<long>>& cell_data) {
  auto values = [&](const std::string& name, long components, long tuples) {
    std::vector<long> kept;
    for (long k = 0; k < components * tuples; ++k) {
      const double v = t.real("value of " + name);
      if (cells && components == 1) kept.push_back(static_cast<long>(v));
    }
    if (cells && components == 1) cell_data[name] = std::move(kept);
  };
  if (kind == "SCALARS") {
    const std::string name(t.next("scalar name"));
    t.next("data type");
    const std::string at = t.where();
    const std::string rest = t.line_text();  // optional component count
    const long components = rest.empty() ? 1 : std::atol(rest.c_str());
    if (components < 1) fail(t.file(), at, "bad component count \"" + rest + "\"");
    t.expect("LOOKUP_TABLE");
    t.next("lookup table name");
    values(name, components, n);
  } else if (kind == "FIELD") {
    t.next("field name");
    for (long a = t.count("number of field arrays"); a > 0; --a) {
      const std::string name(t.next("array name"));
      const long components = t.count("number of components");
      const long tuples = t.count("number of tuples");
      t.next("data type");
      values(name, components, tuples);
    }
  } else if (kind == "VECTORS" || kind == "NORMALS" || kind == "TENSORS") {
    const std::string name(t.next("array name"));
    t.next("data type");
    values(name, kind == "TENSORS" ? 9 : 3, n);
  } else {
    fail(t.file(), t.where(), "unsupported VTK data attribute " + kind);
  }
}

void parse_vtk_legacy(const std::string& text, Collector& c) {
  const std::string& file = c.out.file;
  Tokens t(text, file, "the header");
  const std::string magic = t.line_text();
  if (magic.rfind("# vtk DataFile Version", 0) != 0) fail(file, "line 1", "not a legacy VTK file (no \"# vtk DataFile Version\" line)");
  const bool v5 = magic.find("Version 5") != std::string::npos;
  t.line_text();  // title
  const std::string format = t.line_text();
  if (format == "BINARY") fail(file, "line 3", "binary VTK file: only ASCII .vtk files are supported");
  if (format != "ASCII") fail(file, "line 3", "expected ASCII or BINARY (got \"" + format + "\")");
  t.expect("DATASET");
  const std::string dataset(t.next("dataset type"));
  if (dataset != "UNSTRUCTURED_GRID") fail(file, t.where(), "dataset " + dataset + ": only UNSTRUCTURED_GRID is supported");
  std::vector<double> xyz;
  std::vector<long> offsets{0}, conn, types;
  std::map<std::string, std::vector<long>> cell_data;
  long data_n = 0;
  bool data_cells = false;
  while (!t.done()) {
    const std::string key(t.next("a section keyword"));
    const std::string where = t.where();
    t.set_context(key + " (from " + where + ")");
    if (key == "POINTS") {
      const long n = t.items("number of points", 3);
      t.next("data type");
      xyz.resize(static_cast<size_t>(3 * n));
      for (double& x : xyz) x = t.real("point coordinate");
    } else if (key == "CELLS" && !v5) {
      const long n = t.count("number of cells");
      t.count("connectivity size");
      for (long i = 0; i < n; ++i) {
        for (long k = t.count("number of cell points"); k > 0; --k) conn.push_back(t.count("point index"));
        offsets.push_back(static_cast<long>(conn.size()));
      }
    } else if (key == "CELLS") {
      const long n_offsets = t.items("number of offsets", 1);
      const long n_conn = t.items("connectivity size", 1);
      t.expect("OFFSETS");
      t.next("data type");
      offsets.resize(static_cast<size_t>(n_offsets));
      for (long& o : offsets) o = t.count("offset", LONG_MAX);
      t.expect("CONNECTIVITY");
      t.next("data type");
      conn.resize(static_cast<size_t>(n_conn));
      for (long& p : conn) p = t.count("point index");
    } else if (key == "CELL_TYPES") {
      types.resize(static_cast<size_t>(t.items("number of cell types", 1)));
      for (long& ty : types) ty = t.integer("cell type");
    } else if (key == "CELL_DATA" || key == "POINT_DATA") {
      data_cells = key == "CELL_DATA";
      data_n = t.count("number of tuples");
    } else if (key == "METADATA") {
      // vtk 9's array metadata: read past up to its blank line.
      t.line_text();
      while (!t.line_text().empty() && !t.done()) {
      }
    } else if (data_n > 0 || key == "FIELD") {
      // Point or cell data, or field data of the whole dataset (read past: not a cell array).
      read_legacy_attribute(t, key, data_n, data_cells && data_n > 0, cell_data);
    } else {
      fail(file, where, "unexpected keyword \"" + key + "\"");
    }
  }
  if (offsets.size() != types.size() + 1)
    fail(file, "CELL_TYPES", std::to_string(types.size()) + " cell types for " + std::to_string(offsets.size() - 1) + " cells");
  const std::vector<long>* tags = tag_array(cell_data);
  if (tags && tags->size() != types.size())
    fail(file, "CELL_DATA", "tag array has " + std::to_string(tags->size()) + " values for " + std::to_string(types.size()) + " cells");
  add_vtk_points(xyz, c);
  add_vtk_cells(types, offsets, conn, tags, c);
}

// ---------------------------------------------------------------------------------------------------------------
// VTK XML (.vtu), through expat

// One <DataArray> of a .vtu file: where it is and its text.
struct XmlArray {
  std::string parent;  // Points | Cells | CellData | PointData | ...
  std::string name, format = "ascii";
  long components = 1;
  int line = 0;
  std::string text;
};

struct VtuState {
  std::string file;
  XML_Parser parser = nullptr;
  std::vector<std::string> stack;
  std::vector<XmlArray> arrays;
  bool in_array = false;
  int pieces = 0;
  std::string error;  // the first refusal found inside a callback (expat cannot throw through C)
};

void vtu_start(void* data, const XML_Char* tag, const XML_Char** attrs) {
  VtuState& s = *static_cast<VtuState*>(data);
  const std::string name = tag;
  const int line = static_cast<int>(XML_GetCurrentLineNumber(s.parser));
  auto attr = [&](const char* key) -> std::string {
    for (int i = 0; attrs[i]; i += 2)
      if (std::string(attrs[i]) == key) return attrs[i + 1];
    return "";
  };
  auto refuse = [&](const std::string& problem) {
    if (s.error.empty()) s.error = s.file + ": line " + std::to_string(line) + ": " + problem;
    XML_StopParser(s.parser, XML_FALSE);
  };
  if (name == "VTKFile" && attr("type") != "UnstructuredGrid")
    refuse("VTKFile type \"" + attr("type") + "\": only UnstructuredGrid is supported");
  if (name == "Piece" && ++s.pieces > 1) refuse("more than one Piece: only single-piece .vtu files are supported");
  if (name == "AppendedData") refuse("appended (binary) data: only ASCII .vtu files are supported (DataArray format=\"ascii\")");
  if (name == "DataArray") {
    XmlArray a;
    a.parent = s.stack.empty() ? "" : s.stack.back();
    a.name = attr("Name");
    if (!attr("format").empty()) a.format = attr("format");
    if (!attr("NumberOfComponents").empty()) a.components = std::atol(attr("NumberOfComponents").c_str());
    a.line = line;
    if (a.format != "ascii")
      refuse("DataArray " + (a.name.empty() ? "" : "\"" + a.name + "\" ") + "in <" + a.parent + "> has format \"" +
             a.format + "\": only ASCII .vtu files are supported");
    s.arrays.push_back(std::move(a));
    s.in_array = true;
  }
  s.stack.push_back(name);
}

void vtu_end(void* data, const XML_Char*) {
  VtuState& s = *static_cast<VtuState*>(data);
  s.in_array = false;
  s.stack.pop_back();
}

void vtu_text(void* data, const XML_Char* text, int len) {
  VtuState& s = *static_cast<VtuState*>(data);
  if (s.in_array) s.arrays.back().text.append(text, static_cast<size_t>(len));
}

// The values of an ASCII DataArray, n of them (-1: any number).
template <class T>
std::vector<T> array_values(const XmlArray& a, const std::string& file, long n) {
  Tokens t(a.text, file, "DataArray \"" + a.name + "\" (from line " + std::to_string(a.line) + ")", a.line);
  std::vector<T> v;
  while (!t.done()) {
    if constexpr (std::is_same_v<T, double>) v.push_back(t.real("a number"));
    else v.push_back(t.integer("an integer"));
  }
  if (n >= 0 && static_cast<long>(v.size()) != n)
    fail(file, "line " + std::to_string(a.line), "DataArray \"" + a.name + "\" has " + std::to_string(v.size()) +
                                                     " values, expected " + std::to_string(n));
  return v;
}

const XmlArray& vtu_array(const VtuState& s, const std::string& parent, const std::string& name) {
  for (const XmlArray& a : s.arrays)
    if (a.parent == parent && (name.empty() || a.name == name)) return a;
  fail(s.file, parent, "no DataArray" + (name.empty() ? std::string() : " \"" + name + "\"") + " in <" + parent + ">");
}

void parse_vtu(const std::string& text, Collector& c) {
  VtuState s;
  s.file = c.out.file;
  s.parser = XML_ParserCreate(nullptr);
  XML_SetUserData(s.parser, &s);
  XML_SetElementHandler(s.parser, vtu_start, vtu_end);
  XML_SetCharacterDataHandler(s.parser, vtu_text);
  const bool ok = XML_Parse(s.parser, text.data(), static_cast<int>(text.size()), XML_TRUE) == XML_STATUS_OK;
  const std::string xml_error = ok ? "" : XML_ErrorString(XML_GetErrorCode(s.parser));
  const long xml_line = static_cast<long>(XML_GetCurrentLineNumber(s.parser));
  XML_ParserFree(s.parser);
  if (!s.error.empty()) throw std::invalid_argument(s.error);
  if (!ok) fail(s.file, "line " + std::to_string(xml_line), "malformed or truncated XML: " + xml_error);
  if (s.pieces == 0) fail(s.file, "UnstructuredGrid", "no Piece");
  const std::vector<double> xyz = array_values<double>(vtu_array(s, "Points", ""), s.file, -1);
  if (xyz.size() % 3 != 0) fail(s.file, "Points", "the point coordinates are not a multiple of 3");
  const std::vector<long> conn = array_values<long>(vtu_array(s, "Cells", "connectivity"), s.file, -1);
  std::vector<long> offsets = array_values<long>(vtu_array(s, "Cells", "offsets"), s.file, -1);
  const std::vector<long> types = array_values<long>(vtu_array(s, "Cells", "types"), s.file, static_cast<long>(offsets.size()));
  offsets.insert(offsets.begin(), 0);
  std::map<std::string, std::vector<long>> cell_data;
  for (const XmlArray& a : s.arrays)
    if (a.parent == "CellData" && a.components == 1) cell_data[a.name] = array_values<long>(a, s.file, static_cast<long>(types.size()));
  add_vtk_points(xyz, c);
  add_vtk_cells(types, offsets, conn, tag_array(cell_data), c);
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return ext.empty() ? ext : ext.substr(1);
}

}  // namespace

VolumeMeshFile parse_volume_mesh(const std::string& text, const std::string& format, const std::string& file) {
  VolumeMeshFile out;
  out.file = file;
  Collector c{out, format == "msh" ? "gmsh" : "VTK", {}, {}, {}, {}, 0};
  if (format == "msh")
    parse_gmsh(text, c);
  else if (format == "vtk")
    parse_vtk_legacy(text, c);
  else if (format == "vtu")
    parse_vtu(text, c);
  else
    fail(file, "file name", "unsupported volume mesh format \"." + format + "\" (supported: .msh, .vtu, .vtk)");
  c.finish();
  return out;
}

VolumeMeshFile read_volume_mesh_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) fail(path, "file", "no such volume mesh file");
  const std::string format = lower_extension(path);
  if (format != "msh" && format != "vtk" && format != "vtu")
    fail(path, "file name", "unsupported volume mesh format \"." + format + "\" (supported: .msh, .vtu, .vtk)");
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  if (!in) fail(path, "file", "cannot read volume mesh file");
  return parse_volume_mesh(text.str(), format, path);
}

}  // namespace lumen::physics
