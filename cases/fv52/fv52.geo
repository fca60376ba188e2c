// format: brep (metres; STEP from gmsh would declare millimetres)
// NAFEMS FV52: simply supported "thick" square plate, 10 m x 10 m x 1 m. Metres.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 10, 10, 1};
