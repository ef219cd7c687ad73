// An L-shaped bracket (benchmarks/l_bracket.toml, benchmarks/line_search.py, tests/test_line_search.py): the
// L profile in the xy plane, a vertical arm 0 <= x <= a, 0 <= y <= H and a horizontal arm 0 <= x <= L,
// 0 <= y <= a, extruded by t along z (OpenCASCADE). Lengths in metres.
//
// Physical groups:
//   volume  "bracket"
//   surface "clamp"   the top of the vertical arm, y = H
//   surface "tip"     the end of the horizontal arm, x = L
//   surface "skin"    the rest of the surface
//
// Parameters (DefineConstant; [mesh] parameters = { size = 0.005 } overrides): size, the largest edge.

SetFactory("OpenCASCADE");

DefineConstant[
  L = {0.1, Name "Parameters/length"},
  H = {0.1, Name "Parameters/height"},
  a = {0.02, Name "Parameters/arm width"},
  t = {0.02, Name "Parameters/thickness"},
  size = {0.01, Name "Parameters/size"}
];

Box(1) = {0, 0, 0, a, H, t};
Box(2) = {0, 0, 0, L, a, t};
BooleanUnion(3) = {Volume{1}; Delete;}{Volume{2}; Delete;};

eps = 1e-6;
clamp() = Surface In BoundingBox {-eps, H - eps, -eps, a + eps, H + eps, t + eps};
tip() = Surface In BoundingBox {L - eps, -eps, -eps, L + eps, a + eps, t + eps};
skin() = Abs(Boundary{ Volume{3}; });
skin() -= {clamp(), tip()};

Physical Volume("bracket", 1) = {3};
Physical Surface("clamp", 1) = {clamp()};
Physical Surface("tip", 2) = {tip()};
Physical Surface("skin", 3) = {skin()};

Mesh.MeshSizeMax = size;
Mesh.MeshSizeMin = 0;
