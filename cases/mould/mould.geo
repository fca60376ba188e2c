// Industrial-scale ribbed stamping-mould-like polystyrene part. mm.
// A thick base carrying a rectangular frame and a grid of ribs, with lightening holes.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 800, 500, 30};                       // base
Box(2) = {0, 0, 30, 800, 20, 120};                       // frame walls
Box(3) = {0, 480, 30, 800, 20, 120};
Box(4) = {0, 0, 30, 20, 500, 120};
Box(5) = {780, 0, 30, 20, 500, 120};
ribs[] = {};
For i In {1:6}
  ribs[] += newv; Box(newv) = {i * 800 / 7 - 6, 20, 30, 12, 460, 100};   // transverse ribs
EndFor
For j In {1:3}
  ribs[] += newv; Box(newv) = {20, j * 500 / 4 - 6, 30, 760, 12, 80};    // longitudinal ribs
EndFor
u() = BooleanUnion{ Volume{1}; Delete; }{ Volume{2:5, ribs[]}; Delete; };
holes[] = {};
For i In {0:6}
  For j In {0:3}
    holes[] += newv; Cylinder(newv) = {i * 800 / 7 + 800 / 14, j * 500 / 4 + 500 / 8, -1, 0, 0, 32, 25};
  EndFor
EndFor
BooleanDifference{ Volume{u()}; Delete; }{ Volume{holes[]}; Delete; }
