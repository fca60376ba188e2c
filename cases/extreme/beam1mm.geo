// 1 mm steel beam at millimetre scale: 20 x 1 x 1 mm.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 20, 1, 1};
