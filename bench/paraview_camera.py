"""Frames a ParaView view on a part from the part's own points, whatever its orientation (the
scripts used to assume z up and look from a fixed corner, so a part lying along another axis came
out small or edge-on).

The principal axes of the point cloud (eigenvectors of its covariance, smallest to largest)
give the view: the camera looks mostly along the smallest axis, so the part shows its largest
face, tilted 35° about the largest axis and 15° about the middle one so that depth (and a mode
moving along the smallest axis) still shows; up is the middle axis made orthogonal to the
view direction, so the longest extent lies across the landscape picture. The distance is the
smallest at which every point, in perspective and with `margin`, lies within both the height
and the width of the picture (less the strip of the scalar bar on the right) at the view angle.
"""
import math

import numpy as np
from paraview import servermanager
from vtkmodules.util.numpy_support import vtk_to_numpy


def points_of(source):
    """The points of a (merged) source as an n×3 numpy array."""
    data = servermanager.Fetch(source)
    return vtk_to_numpy(data.GetPoints().GetData()).astype(float)


def principal_axes(p):
    """Smallest, middle and largest principal axes of the points (unit vectors, signs fixed:
    each axis's largest component positive, so the same part always gets the same view)."""
    c = p - p.mean(axis=0)
    w, v = np.linalg.eigh(c.T @ c / len(p))
    axes = []
    for k in range(3):
        a = v[:, k]
        if a[np.argmax(np.abs(a))] < 0:
            a = -a
        axes.append(a)
    return axes


def frame(view, source, margin=1.15, tilt_deg=(35.0, 15.0), usable=0.86):
    """Points the camera of `view` at `source` as the module docstring says, within the left
    `usable` fraction of the picture's width (the scalar bar takes the right edge); returns the
    view direction, up vector and distance."""
    p = points_of(source)
    small, mid, large = principal_axes(p)
    a, b = (math.radians(t) for t in tilt_deg)
    # From the smallest axis, turned toward the middle one (about the largest) and toward the
    # largest one (about the middle).
    d = math.cos(a) * math.cos(b) * small + math.sin(a) * math.cos(b) * mid + math.sin(b) * large
    d /= np.linalg.norm(d)
    up = mid - (mid @ d) * d
    up /= np.linalg.norm(up)
    # The camera looks along -d: the picture's right is (-d) × up.
    right = np.cross(up, d)
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre = 0.5 * (lo + hi)
    # The projected extent on the picture's axes, about the centre.
    x, y = (p - centre) @ right, (p - centre) @ up
    mx, my = 0.5 * (x.max() + x.min()), 0.5 * (y.max() + y.min())
    focal = centre + mx * right + my * up
    width, height = view.ViewSize
    aspect = width / height
    t = math.tan(0.5 * math.radians(view.CameraViewAngle))
    # Each point, `z` nearer the camera than the focal plane, is seen at lateral offset
    # x / (dist - z): the nearest distance at which every point fits (with the margin) is the
    # largest of |x| / tan + z over the points, in each direction of the picture.
    z = (p - centre) @ d
    dist = max(
        (margin * np.abs(x - mx) / (t * aspect * usable) + z).max(),
        (margin * np.abs(y - my) / t + z).max(),
    )
    # The part's centre moves left of the picture's centre by half the width given up.
    focal = focal + (1.0 - usable) * dist * t * aspect * right
    view.CameraFocalPoint = list(focal)
    view.CameraPosition = list(focal + dist * d)
    view.CameraViewUp = list(up)
    return d, up, dist
