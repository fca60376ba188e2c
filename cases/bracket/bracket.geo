// Aluminium L-bracket with a hole in its upright, a free body. mm.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 80, 60, 8};              // base
Box(2) = {0, 0, 8, 8, 60, 52};              // upright
BooleanUnion(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
Cylinder(4) = {-1, 30, 35, 10, 0, 0, 10};   // hole through the upright, diameter 20
BooleanDifference{ Volume{3}; Delete; }{ Volume{4}; Delete; }
