"""Opens a basis's XDMF sidecar in ParaView (pvpython, headless, no h5py there) and prints what
ParaView read as one JSON object, for the test to compare with the HDF5 file: per grid its
points, three cells' point ids, and every point array's name, components and tuples at three
points (first, middle, last).

    pvpython --force-offscreen-rendering sidecar_dump.py BASIS.xdmf
"""
import json
import sys

from paraview import servermanager as sm
from paraview.simple import XDMFReader

reader = XDMFReader(FileNames=[sys.argv[1]])
reader.UpdatePipeline()
data = sm.Fetch(reader)
out = {}
for b in range(data.GetNumberOfBlocks()):
    g = data.GetBlock(b)
    n, m = g.GetNumberOfPoints(), g.GetNumberOfCells()
    picks = sorted({0, n // 2, n - 1})
    cells = sorted({0, m // 2, m - 1})
    pd = g.GetPointData()
    out[data.GetMetaData(b).Get(data.NAME())] = {
        "points": [g.GetPoint(i) for i in range(n)],
        "cells": {str(e): [g.GetCell(e).GetPointId(i) for i in range(g.GetCell(e).GetNumberOfPoints())] for e in cells},
        "cell_type": g.GetCell(0).GetClassName(),
        "arrays": [
            {
                "name": pd.GetArrayName(i),
                "components": pd.GetArray(i).GetNumberOfComponents(),
                "tuples": {str(p): pd.GetArray(i).GetTuple(p) for p in picks},
            }
            for i in range(pd.GetNumberOfArrays())
        ],
    }
print(json.dumps(out))
