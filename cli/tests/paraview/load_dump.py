"""Opens a basis's XDMF sidecar in ParaView (pvpython, headless) and prints, as one JSON object,
the point arrays a load case's user asks for by name: `fixed` and the arrays named on the
command line, every tuple (from the first grid that has the array: the global space, or its
vertices grid for a stress tensor), the first grid's point count and its field data.

    pvpython --force-offscreen-rendering load_dump.py BASIS.xdmf ARRAY [ARRAY ...]
"""
import json
import sys

from paraview import servermanager as sm
from paraview.simple import XDMFReader

reader = XDMFReader(FileNames=[sys.argv[1]])
reader.UpdatePipeline()
data = sm.Fetch(reader)
blocks = [data.GetBlock(i) for i in range(data.GetNumberOfBlocks())] if hasattr(data, "GetNumberOfBlocks") else [data]
grid = blocks[0]
pd, fd = grid.GetPointData(), grid.GetFieldData()
out = {"points": grid.GetNumberOfPoints(), "arrays": {}, "field": {}}
# Each array from the first grid that has it (a load case's stress tensor is on the vertices grid).
for name in ["fixed"] + sys.argv[2:]:
    a = next((b.GetPointData().GetArray(name) for b in blocks if b.GetPointData().GetArray(name) is not None), None)
    if a is None:
        sys.exit("no point array %r; the grids have %s" % (name, [[b.GetPointData().GetArrayName(i) for i in range(b.GetPointData().GetNumberOfArrays())] for b in blocks]))
    out["arrays"][name] = [a.GetTuple(i) for i in range(a.GetNumberOfTuples())]
for i in range(fd.GetNumberOfArrays()):
    a = fd.GetArray(i)
    out["field"][fd.GetArrayName(i)] = [a.GetTuple(k)[0] for k in range(a.GetNumberOfTuples())]
print(json.dumps(out))
