// One octant (x, y, z >= 0) of a thick-walled hollow sphere, inner radius A, outer radius B, with curved
// second-order tetrahedra (10 nodes: the spheres are represented to O(h^3)). OpenCASCADE. Lengths in metres.
//
// Physical groups:
//   volume  "wall"
//   surface "inner"  r = A (the cavity: a follower pressure, or its volume prescribed)
//   surface "outer"  r = B
//   surface "xmin", "ymin", "zmin"  the symmetry planes x = 0, y = 0, z = 0
//
// Parameters (DefineConstant; [mesh] parameters = { size = 0.1 } overrides): A, B, size (the largest edge).

SetFactory("OpenCASCADE");

DefineConstant[
  A = {1.0, Name "Parameters/inner radius"},
  B = {1.5, Name "Parameters/outer radius"},
  size = {0.25, Name "Parameters/size"}
];

Sphere(1) = {0, 0, 0, B};
Sphere(2) = {0, 0, 0, A};
BooleanDifference(3) = {Volume{1}; Delete;}{Volume{2}; Delete;};
Box(4) = {0, 0, 0, 2 * B, 2 * B, 2 * B};
BooleanIntersection(5) = {Volume{3}; Delete;}{Volume{4}; Delete;};

eps = 1e-6;
xmin() = Surface In BoundingBox {-eps, -eps, -eps, eps, B + eps, B + eps};
ymin() = Surface In BoundingBox {-eps, -eps, -eps, B + eps, eps, B + eps};
zmin() = Surface In BoundingBox {-eps, -eps, -eps, B + eps, B + eps, eps};
inner() = Surface In BoundingBox {-eps, -eps, -eps, A + eps, A + eps, A + eps};
inner() -= {xmin(), ymin(), zmin()};
all() = Abs(Boundary{ Volume{5}; });
outer() = all();
outer() -= {xmin(), ymin(), zmin(), inner()};

Physical Volume("wall") = {5};
Physical Surface("inner") = {inner()};
Physical Surface("outer") = {outer()};
Physical Surface("xmin") = {xmin()};
Physical Surface("ymin") = {ymin()};
Physical Surface("zmin") = {zmin()};

Mesh.MeshSizeMax = size;
Mesh.MeshSizeMin = 0;
Mesh.ElementOrder = 2;
Mesh.HighOrderOptimize = 1;
