// A quarter (x, y >= 0) of a truncated ellipsoidal shell, an idealised left ventricle: the region between the
// inner ellipsoid x^2/ai^2 + y^2/ai^2 + z^2/ci^2 = 1 and the outer one (ao, ao, co), below the base plane
// z = 0. Curved second-order tetrahedra (10 nodes). OpenCASCADE. Lengths in metres.
//
// Physical groups:
//   volume  "wall"
//   surface "endocardium"  the inner surface (the cavity: pressure, or its volume prescribed)
//   surface "epicardium"   the outer surface
//   surface "base"         z = 0
//   surface "xmin", "ymin" the symmetry planes x = 0, y = 0
//
// Parameters (DefineConstant; [mesh] parameters = { size = 0.004 } overrides): ai, ci, ao, co, size.

SetFactory("OpenCASCADE");
Geometry.OCCBoundsUseStl = 1;  // exact bounding boxes of the dilated (B-spline) surfaces (see eps below)

DefineConstant[
  ai = {0.025, Name "Parameters/inner equatorial radius"},
  ci = {0.060, Name "Parameters/inner long radius"},
  ao = {0.035, Name "Parameters/outer equatorial radius"},
  co = {0.070, Name "Parameters/outer long radius"},
  size = {0.006, Name "Parameters/size"}
];

Sphere(1) = {0, 0, 0, 1};
Dilate {{0, 0, 0}, {ao, ao, co}} { Volume{1}; }
Sphere(2) = {0, 0, 0, 1};
Dilate {{0, 0, 0}, {ai, ai, ci}} { Volume{2}; }
BooleanDifference(3) = {Volume{1}; Delete;}{Volume{2}; Delete;};
Box(4) = {0, 0, -2 * co, 2 * ao, 2 * ao, 2 * co};
BooleanIntersection(5) = {Volume{3}; Delete;}{Volume{4}; Delete;};

eps = 1e-4;
xmin() = Surface In BoundingBox {-eps, -eps, -co - eps, eps, ao + eps, eps};
ymin() = Surface In BoundingBox {-eps, -eps, -co - eps, ao + eps, eps, eps};
base() = Surface In BoundingBox {-eps, -eps, -eps, ao + eps, ao + eps, eps};
endo() = Surface In BoundingBox {-eps, -eps, -ci - eps, ai + eps, ai + eps, eps};
endo() -= {xmin(), ymin(), base()};
all() = Abs(Boundary{ Volume{5}; });
epi() = all();
epi() -= {xmin(), ymin(), base(), endo()};

Physical Volume("wall") = {5};
Physical Surface("endocardium") = {endo()};
Physical Surface("epicardium") = {epi()};
Physical Surface("base") = {base()};
Physical Surface("xmin") = {xmin()};
Physical Surface("ymin") = {ymin()};

Mesh.MeshSizeMax = size;
Mesh.MeshSizeMin = 0;
Mesh.ElementOrder = 2;
Mesh.HighOrderOptimize = 1;
