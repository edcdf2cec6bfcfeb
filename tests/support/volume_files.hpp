// Test support: a tet mesh with tagged wall triangles written as each volume mesh format Lumen reads (gmsh .msh
// v2.2 and v4.1, VTK .vtu and legacy .vtk, all ASCII), from the format specifications (not from Lumen's readers).
#pragma once

#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "physics/types.hpp"

namespace lumen::test {

// A mesh to write: nodes, tets, and surface triangles with their tags (the physical surfaces' numbers).
struct TaggedVolume {
  Points nodes;                  // n x 3
  Tets tets;                     // m x 4, positive
  std::vector<Tris> surfaces;    // triangles of each tagged surface
  std::vector<int> tags;         // tag of each surface
  std::vector<std::string> names;  // gmsh physical name of each surface
};
// The physical tag the gmsh writers give the volume.
constexpr int kVolumeTag = 100;

inline std::ostringstream exact_stream() {
  std::ostringstream s;
  s.precision(std::numeric_limits<double>::max_digits10);
  return s;
}

inline int total_triangles(const TaggedVolume& v) {
  int n = 0;
  for (const Tris& s : v.surfaces) n += static_cast<int>(s.rows());
  return n;
}

// gmsh MSH 2.2 ASCII: triangles (type 2) with tags (physical, elementary), then tets (type 4); node ids from 1.
inline std::string write_msh22(const TaggedVolume& v) {
  std::ostringstream s = exact_stream();
  s << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n" << v.surfaces.size() + 1 << "\n";
  for (size_t i = 0; i < v.surfaces.size(); ++i) s << "2 " << v.tags[i] << " \"" << v.names[i] << "\"\n";
  s << "3 " << kVolumeTag << " \"wall\"\n$EndPhysicalNames\n$Nodes\n" << v.nodes.rows() << "\n";
  for (int i = 0; i < v.nodes.rows(); ++i) s << i + 1 << " " << v.nodes(i, 0) << " " << v.nodes(i, 1) << " " << v.nodes(i, 2) << "\n";
  s << "$EndNodes\n$Elements\n" << total_triangles(v) + v.tets.rows() << "\n";
  int id = 1;
  for (size_t i = 0; i < v.surfaces.size(); ++i)
    for (int t = 0; t < v.surfaces[i].rows(); ++t)
      s << id++ << " 2 2 " << v.tags[i] << " " << i + 1 << " " << v.surfaces[i](t, 0) + 1 << " "
        << v.surfaces[i](t, 1) + 1 << " " << v.surfaces[i](t, 2) + 1 << "\n";
  for (int t = 0; t < v.tets.rows(); ++t)
    s << id++ << " 4 2 " << kVolumeTag << " 1 " << v.tets(t, 0) + 1 << " " << v.tets(t, 1) + 1 << " "
      << v.tets(t, 2) + 1 << " " << v.tets(t, 3) + 1 << "\n";
  s << "$EndElements\n";
  return s.str();
}

// gmsh MSH 4.1 ASCII: one surface entity per tagged surface (its physical tag in $Entities), one volume entity.
inline std::string write_msh41(const TaggedVolume& v) {
  std::ostringstream s = exact_stream();
  const size_t ns = v.surfaces.size();
  s << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n" << ns + 1 << "\n";
  for (size_t i = 0; i < ns; ++i) s << "2 " << v.tags[i] << " \"" << v.names[i] << "\"\n";
  s << "3 " << kVolumeTag << " \"wall\"\n$EndPhysicalNames\n$Entities\n0 0 " << ns << " 1\n";
  for (size_t i = 0; i < ns; ++i) s << i + 1 << " 0 0 0 1 1 1 1 " << v.tags[i] << " 0\n";
  s << "1 0 0 0 1 1 1 1 " << kVolumeTag << " " << ns;
  for (size_t i = 0; i < ns; ++i) s << " " << i + 1;
  s << "\n$EndEntities\n$Nodes\n1 " << v.nodes.rows() << " 1 " << v.nodes.rows() << "\n3 1 0 " << v.nodes.rows() << "\n";
  for (int i = 0; i < v.nodes.rows(); ++i) s << i + 1 << "\n";
  for (int i = 0; i < v.nodes.rows(); ++i) s << v.nodes(i, 0) << " " << v.nodes(i, 1) << " " << v.nodes(i, 2) << "\n";
  const int n_elements = total_triangles(v) + static_cast<int>(v.tets.rows());
  s << "$EndNodes\n$Elements\n" << ns + 1 << " " << n_elements << " 1 " << n_elements << "\n";
  int id = 1;
  for (size_t i = 0; i < ns; ++i) {
    s << "2 " << i + 1 << " 2 " << v.surfaces[i].rows() << "\n";
    for (int t = 0; t < v.surfaces[i].rows(); ++t)
      s << id++ << " " << v.surfaces[i](t, 0) + 1 << " " << v.surfaces[i](t, 1) + 1 << " " << v.surfaces[i](t, 2) + 1 << "\n";
  }
  s << "3 1 4 " << v.tets.rows() << "\n";
  for (int t = 0; t < v.tets.rows(); ++t)
    s << id++ << " " << v.tets(t, 0) + 1 << " " << v.tets(t, 1) + 1 << " " << v.tets(t, 2) + 1 << " " << v.tets(t, 3) + 1 << "\n";
  s << "$EndElements\n";
  return s.str();
}

// VTK cell types: triangle, tetra.
constexpr int kVtkTriangle = 5, kVtkTetra = 10;

// The cells in order (the surfaces' triangles, then the tets) as (type, points, tag) for the VTK writers.
struct VtkCell {
  int type;
  std::vector<int> points;
  int tag;
};
inline std::vector<VtkCell> vtk_cells(const TaggedVolume& v) {
  std::vector<VtkCell> cells;
  for (size_t i = 0; i < v.surfaces.size(); ++i)
    for (int t = 0; t < v.surfaces[i].rows(); ++t)
      cells.push_back({kVtkTriangle, {v.surfaces[i](t, 0), v.surfaces[i](t, 1), v.surfaces[i](t, 2)}, v.tags[i]});
  for (int t = 0; t < v.tets.rows(); ++t)
    cells.push_back({kVtkTetra, {v.tets(t, 0), v.tets(t, 1), v.tets(t, 2), v.tets(t, 3)}, kVolumeTag});
  return cells;
}

// VTK XML UnstructuredGrid, ASCII data arrays; the tags in cell data "gmsh:physical".
inline std::string write_vtu(const TaggedVolume& v) {
  std::ostringstream s = exact_stream();
  const std::vector<VtkCell> cells = vtk_cells(v);
  s << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    << "<UnstructuredGrid>\n<Piece NumberOfPoints=\"" << v.nodes.rows() << "\" NumberOfCells=\"" << cells.size() << "\">\n"
    << "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (int i = 0; i < v.nodes.rows(); ++i) s << v.nodes(i, 0) << " " << v.nodes(i, 1) << " " << v.nodes(i, 2) << "\n";
  s << "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const VtkCell& c : cells)
    for (int p : c.points) s << p << " ";
  s << "\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  size_t offset = 0;
  for (const VtkCell& c : cells) s << (offset += c.points.size()) << " ";
  s << "\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (const VtkCell& c : cells) s << c.type << " ";
  s << "\n</DataArray>\n</Cells>\n<CellData>\n<DataArray type=\"Int32\" Name=\"gmsh:physical\" format=\"ascii\">\n";
  for (const VtkCell& c : cells) s << c.tag << " ";
  s << "\n</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  return s.str();
}

// VTK legacy 4.2 ASCII unstructured grid; the tags as SCALARS "gmsh:physical".
inline std::string write_vtk(const TaggedVolume& v) {
  std::ostringstream s = exact_stream();
  const std::vector<VtkCell> cells = vtk_cells(v);
  size_t size = 0;
  for (const VtkCell& c : cells) size += c.points.size() + 1;
  s << "# vtk DataFile Version 4.2\nwritten by a Lumen test\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS "
    << v.nodes.rows() << " double\n";
  for (int i = 0; i < v.nodes.rows(); ++i) s << v.nodes(i, 0) << " " << v.nodes(i, 1) << " " << v.nodes(i, 2) << "\n";
  s << "CELLS " << cells.size() << " " << size << "\n";
  for (const VtkCell& c : cells) {
    s << c.points.size();
    for (int p : c.points) s << " " << p;
    s << "\n";
  }
  s << "CELL_TYPES " << cells.size() << "\n";
  for (const VtkCell& c : cells) s << c.type << "\n";
  s << "CELL_DATA " << cells.size() << "\nSCALARS gmsh:physical int 1\nLOOKUP_TABLE default\n";
  for (const VtkCell& c : cells) s << c.tag << "\n";
  return s.str();
}

}  // namespace lumen::test
