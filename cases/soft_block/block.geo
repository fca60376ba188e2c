// Soft block, 50 x 50 x 50 mm, held on its base (z = 0) and pressed on its top.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 50, 50, 50};
