// Steel cantilever, 1000 x 100 x 50 mm (x: length, y: width, z: thickness).
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1000, 100, 50};
