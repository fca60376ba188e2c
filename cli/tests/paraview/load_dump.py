"""Opens a basis's XDMF sidecar in ParaView (pvpython, headless) and prints, as one JSON object,
the point arrays a load case's user asks for by name: `fixed` and the arrays named on the
command line, every tuple of the first grid (the global space), and its field data.

    pvpython --force-offscreen-rendering load_dump.py BASIS.xdmf ARRAY [ARRAY ...]
"""
import json
import sys

from paraview import servermanager as sm
from paraview.simple import XDMFReader

reader = XDMFReader(FileNames=[sys.argv[1]])
reader.UpdatePipeline()
data = sm.Fetch(reader)
grid = data.GetBlock(0) if hasattr(data, "GetNumberOfBlocks") else data
pd, fd = grid.GetPointData(), grid.GetFieldData()
out = {"points": grid.GetNumberOfPoints(), "arrays": {}, "field": {}}
for name in ["fixed"] + sys.argv[2:]:
    a = pd.GetArray(name)
    if a is None:
        sys.exit("no point array %r; the grid has %s" % (name, [pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())]))
    out["arrays"][name] = [a.GetTuple(i) for i in range(a.GetNumberOfTuples())]
for i in range(fd.GetNumberOfArrays()):
    a = fd.GetArray(i)
    out["field"][fd.GetArrayName(i)] = [a.GetTuple(k)[0] for k in range(a.GetNumberOfTuples())]
print(json.dumps(out))
