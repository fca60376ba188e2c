// 200:1 thin plate: 200 x 200 x 1 mm.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 200, 200, 1};
