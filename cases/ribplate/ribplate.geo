// The chapter's test part: a plate carrying four beams (ribs), polystyrene-like. mm.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 200, 150, 8};            // plate
Box(2) = {20, 20, 8, 60, 8, 40};            // rib 1, along x
Box(3) = {120, 20, 8, 60, 8, 30};           // rib 2, along x, lower
Box(4) = {20, 100, 8, 8, 40, 50};           // rib 3, along y, taller
Box(5) = {140, 90, 8, 10, 45, 35};          // rib 4, along y, thicker
BooleanUnion{ Volume{1}; Delete; }{ Volume{2, 3, 4, 5}; Delete; }
