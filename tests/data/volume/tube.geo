// A hollow cylinder meshed by gmsh (tests/physics/test_volume_mesh_files.cpp reads what gmsh writes of it):
// inner radius 10 mm, outer 13 mm, length 40 mm along +z from z = 0, linear tets. Physical surfaces "inner" (1),
// "outer" (2), "ends" (3), physical volume "wall" (4). Regenerate (Debian's gmsh 4.8):
//   gmsh -3 tube.geo -format msh41 -o tube41.msh && gmsh -3 tube.geo -format msh22 -o tube22.msh &&
//   gmsh -3 tube.geo -format vtk -o tube.vtk
SetFactory("OpenCASCADE");
Cylinder(1) = {0, 0, 0, 0, 0, 40, 13};
Cylinder(2) = {0, 0, -1, 0, 0, 42, 10};
BooleanDifference(3) = {Volume{1}; Delete;}{Volume{2}; Delete;};
eps = 1e-3;
boundary() = Boundary{Volume{3};};
inner() = Surface In BoundingBox{-10 - eps, -10 - eps, -eps, 10 + eps, 10 + eps, 40 + eps};
ends() = Surface In BoundingBox{-13 - eps, -13 - eps, -eps, 13 + eps, 13 + eps, eps};
ends() += Surface In BoundingBox{-13 - eps, -13 - eps, 40 - eps, 13 + eps, 13 + eps, 40 + eps};
outer() = boundary();
outer() -= inner();
outer() -= ends();
Physical Surface("inner", 1) = inner();
Physical Surface("outer", 2) = outer();
Physical Surface("ends", 3) = ends();
Physical Volume("wall", 4) = {3};
Mesh.MeshSizeMax = 4;
Mesh.MeshSizeMin = 2;
