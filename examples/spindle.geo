// A spindle (fusiform) muscle for examples/spindle.toml: a body of revolution about the z axis,
// r(z) = r_end + (r_belly - r_end) sin(pi z / L)^2 for 0 <= z <= L, lofted through circular
// sections (OpenCASCADE), with flat ends of radius r_end. Lengths in metres.
//
// Physical groups (the names the configuration uses):
//   volume  "muscle"
//   surface "origin"     the end z = 0
//   surface "insertion"  the end z = L
//   surface "side"       the curved surface
//
// Parameters: DefineConstant values, which [mesh] parameters = { size = 0.004 } of a configuration
// (or gmsh -setnumber size 0.004) overrides. size is the largest element edge.

SetFactory("OpenCASCADE");

DefineConstant[
  L = {0.08, Name "Parameters/length"},
  r_belly = {0.012, Name "Parameters/belly radius"},
  r_end = {0.005, Name "Parameters/end radius"},
  sections = {9, Name "Parameters/sections"},
  size = {0.005, Name "Parameters/size"}
];

For i In {0 : sections - 1}
  z = L * i / (sections - 1);
  r = r_end + (r_belly - r_end) * Sin(Pi * z / L)^2;
  Circle(i + 1) = {0, 0, z, r};
  Curve Loop(i + 1) = {i + 1};
EndFor
ThruSections(1) = {1 : sections};

eps = 1e-3 * L;
origin() = Surface In BoundingBox {-r_belly - eps, -r_belly - eps, -eps, r_belly + eps, r_belly + eps, eps};
insertion() = Surface In BoundingBox {-r_belly - eps, -r_belly - eps, L - eps, r_belly + eps, r_belly + eps, L + eps};
side() = Abs(Boundary{ Volume{1}; });
side() -= {origin(), insertion()};

Physical Volume("muscle", 1) = {1};
Physical Surface("origin", 1) = {origin()};
Physical Surface("insertion", 2) = {insertion()};
Physical Surface("side", 3) = {side()};

Mesh.MeshSizeMax = size;
Mesh.MeshSizeMin = 0;
Mesh.MeshSizeFromCurvature = 12;
