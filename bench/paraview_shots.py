"""Renders a basis's XDMF sidecar in ParaView, headless: the first mode's shape (warped, coloured
by displacement magnitude) and the first mode's stress field (von Mises, computed by ParaView
from the stored tensor) — the pictures in docs/paraview/.

    pvpython --force-offscreen-rendering bench/paraview_shots.py BASIS.xdmf OUTDIR [MODE]
"""
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from paraview_camera import frame  # noqa: E402

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetColorTransferFunction,
                             Hide, MergeBlocks, PythonCalculator, SaveScreenshot, Show,
                             WarpByVector,
                             XDMFReader)

xdmf, out = sys.argv[1], sys.argv[2]
mode = int(sys.argv[3]) if len(sys.argv) > 3 else 1
os.makedirs(out, exist_ok=True)
base = os.path.splitext(os.path.basename(xdmf))[0]
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 800]
view.OrientationAxesVisibility = 1
view.Background = [0.11, 0.13, 0.15]


def grid(name):
    r = XDMFReader(FileNames=[xdmf])
    grids = list(r.GetProperty("GridInfo")[0::2]) if r.GetProperty("GridInfo") else []
    r.GridStatus = [name]
    r.UpdatePipeline()
    return MergeBlocks(Input=r), grids


def array_named(src, mode, what):
    """The array `mode_07_<what>` (zero-padded to two digits, or to the width of the mode count)."""
    names = src.PointData.keys()
    hit = [n for n in names if re.fullmatch(r"mode_0*%d_%s" % (mode, what), n)]
    if not hit:
        sys.exit("no point array mode_%02d_%s in %s: %s" % (mode, what, xdmf, names))
    return hit[0]


# 1. The mode's shape, warped so the largest displacement is 8 % of the part's size.
shape, _ = grid("global")
name = array_named(shape, mode, "displacement")
lo, hi = shape.GetDataInformation().GetBounds()[0::2], shape.GetDataInformation().GetBounds()[1::2]
size = max(h - l for l, h in zip(lo, hi))
peak = shape.PointData[name].GetRange(-1)[1]
warp = WarpByVector(Input=shape, Vectors=["POINTS", name], ScaleFactor=0.08 * size / peak)
Show(shape, view).Opacity = 0.15
d = Show(warp, view)
ColorBy(d, ("POINTS", name, "Magnitude"))
d.SetScalarBarVisibility(view, True)
GetColorTransferFunction(name).ApplyPreset("Cool to Warm", True)
frame(view, shape)
SaveScreenshot(os.path.join(out, "%s_mode%d_shape.png" % (base, mode)), view, ImageResolution=[1200, 800])
Hide(warp, view)
Hide(shape, view)

# 2. The same mode's stress: von Mises from the Tensor6 (xx yy zz xy yz xz in ParaView's order).
stress, _ = grid("global vertices")
sname = array_named(stress, mode, "stress")
# numpy through PythonCalculator, which hands a Tensor6 array over as n 3×3 symmetric matrices.
t = "inputs[0].PointData[%r]" % sname
vm = PythonCalculator(Input=stress, ArrayName="von Mises (Pa per unit q)", Expression=(
    "sqrt(0.5*((%(t)s[:,0,0]-%(t)s[:,1,1])**2+(%(t)s[:,1,1]-%(t)s[:,2,2])**2+(%(t)s[:,2,2]-%(t)s[:,0,0])**2)"
    "+3*(%(t)s[:,0,1]**2+%(t)s[:,1,2]**2+%(t)s[:,0,2]**2))" % {"t": t}))
d = Show(vm, view)
ColorBy(d, ("POINTS", "von Mises (Pa per unit q)"))
d.SetScalarBarVisibility(view, True)
GetColorTransferFunction("von Mises (Pa per unit q)").ApplyPreset("Cool to Warm", True)
frame(view, stress)
SaveScreenshot(os.path.join(out, "%s_mode%d_von_mises.png" % (base, mode)), view, ImageResolution=[1200, 800])
print("wrote", out)
