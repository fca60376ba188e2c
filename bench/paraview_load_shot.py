"""Renders one load case of a basis's XDMF sidecar in ParaView, headless: the part deformed by
`load_<NAME>_displacement` (scaled so the largest displacement is 8 % of the part's size),
coloured by `load_<NAME>_von_mises`, over the undeformed part, with the supported nodes
(`fixed` = 1) drawn as points — the load-case picture in docs/paraview/.

    pvpython --force-offscreen-rendering bench/paraview_load_shot.py BASIS.xdmf NAME OUT.png
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from paraview_camera import frame  # noqa: E402

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetColorTransferFunction, MergeBlocks,
                             SaveScreenshot, Show, Threshold, WarpByVector, XDMFReader)

xdmf, name, png = sys.argv[1], sys.argv[2], sys.argv[3]
u, vm = "load_%s_displacement" % name, "load_%s_von_mises" % name
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 800]
view.OrientationAxesVisibility = 1
view.Background = [0.11, 0.13, 0.15]
reader = XDMFReader(FileNames=[xdmf])
reader.GridStatus = ["global"]
grid = MergeBlocks(Input=reader)
grid.UpdatePipeline()
if u not in grid.PointData.keys() or "fixed" not in grid.PointData.keys():
    sys.exit("no %s or fixed in %s: %s" % (u, xdmf, grid.PointData.keys()))
b = grid.GetDataInformation().GetBounds()
size = max(b[1] - b[0], b[3] - b[2], b[5] - b[4])
peak = grid.PointData[u].GetRange(-1)[1]
warp = WarpByVector(Input=grid, Vectors=["POINTS", u], ScaleFactor=0.08 * size / peak)
Show(grid, view).Opacity = 0.15
d = Show(warp, view)
ColorBy(d, ("POINTS", vm))
d.SetScalarBarVisibility(view, True)
GetColorTransferFunction(vm).ApplyPreset("Cool to Warm", True)
held = Threshold(Input=grid, Scalars=["POINTS", "fixed"], LowerThreshold=0.5, UpperThreshold=1.5)
h = Show(held, view)
h.SetRepresentationType("Points")
h.PointSize = 4
h.AmbientColor = h.DiffuseColor = [1.0, 0.85, 0.2]
h.ColorArrayName = ["POINTS", ""]
frame(view, grid)
SaveScreenshot(png, view, ImageResolution=[1200, 800])
print("wrote", png)
