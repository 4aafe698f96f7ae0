"""Open an arfem ``fields.xdmf3`` in ParaView itself and save a picture.

Run with ParaView's Python (Debian: ``apt-get install paraview``)::

    pvpython --force-offscreen-rendering benchmarks/open_in_paraview.py \\
        OUT/fields/fields.xdmf3 OUT/paraview.png

(without an X display: ``LIBGL_ALWAYS_SOFTWARE=1 xvfb-run -a -s "-screen 0 1600x1000x24
+extension GLX" pvpython benchmarks/open_in_paraview.py ...``). It opens the file with each of
ParaView's XDMF readers (``Xdmf3ReaderT``, the "Xdmf3 Reader (Top Level Partition)",
and ``XDMFReader``, the XDMF 2 reader), prints for each the time steps, the cell types,
the point arrays and the wall time, then draws ``T_C`` at the hottest time step on the
surface warped by ``displacement_m`` and saves the picture. It exits non-zero if no
reader reads the file.
"""
import os
import sys
import time

from paraview import servermanager
from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetColorTransferFunction,
                             GetDisplayProperties, Render, ResetCamera, SaveScreenshot, Show,
                             UpdatePipeline, WarpByVector, XDMFReader)

try:
    from paraview.simple import Xdmf3ReaderT
except ImportError:                      # older ParaView builds
    Xdmf3ReaderT = None

# VTK cell type ids of the cells arfem writes
CELL_NAMES = {9: "quad", 12: "hexahedron", 23: "quadratic quad (8)", 25: "quadratic hexahedron (20)",
              28: "biquadratic quad (9)", 29: "triquadratic hexahedron (27)"}


def describe(name, reader):
    t0 = time.perf_counter()
    times = list(reader.TimestepValues) if reader.TimestepValues else []
    UpdatePipeline(time=times[-1] if times else 0.0, proxy=reader)
    data = servermanager.Fetch(reader)
    wall = time.perf_counter() - t0
    if data.IsA("vtkMultiBlockDataSet"):
        data = data.GetBlock(0)
    types = sorted({data.GetCellType(i) for i in range(data.GetNumberOfCells())})
    arrays = [data.GetPointData().GetArrayName(i) for i in range(data.GetPointData().GetNumberOfArrays())]
    comps = {a: data.GetPointData().GetArray(a).GetNumberOfComponents() for a in arrays}
    print(f"{name}: {len(times)} time steps {times[:3]}...{times[-1:]} s, {data.GetNumberOfPoints()} "
          f"points, {data.GetNumberOfCells()} cells of type {[CELL_NAMES.get(t, t) for t in types]}, "
          f"point arrays {comps}, read in {wall:.2f} s")
    return times


def main(path, png):
    ok = None
    for name, make in (("Xdmf3ReaderT", (lambda: Xdmf3ReaderT(FileName=[path])) if Xdmf3ReaderT else None),
                       ("XDMFReader", lambda: XDMFReader(FileNames=[path]))):
        if make is None:
            continue
        try:
            reader = make()
            times = describe(name, reader)
            ok = ok or (reader, times)
        except Exception as exc:         # report and try the other reader
            print(f"{name}: failed: {exc}")
    if ok is None:
        return 1
    reader, times = ok
    t0 = time.perf_counter()
    # the hottest instant (the peak of the duty cycle), not the cold end of it
    hottest, tmax = times[-1] if times else 0.0, -1e300
    for t in times:
        UpdatePipeline(time=t, proxy=reader)
        hi = reader.PointData["T_C"].GetRange()[1]
        if hi > tmax:
            hottest, tmax = t, hi
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [1400, 600]
    view.ViewTime = hottest
    warp = WarpByVector(Input=reader, Vectors=["POINTS", "displacement_m"], ScaleFactor=1000.0)
    disp = Show(warp, view)
    ColorBy(disp, ("POINTS", "T_C"))
    disp.SetScalarBarVisibility(view, True)
    GetColorTransferFunction("T_C").ApplyPreset("Viridis (matplotlib)", True)
    view.CameraPosition = [0.0, 2.0, 0.4]
    view.CameraFocalPoint = [0.0, 0.0, 0.4]
    view.CameraViewUp = [1.0, 0.0, 0.0]
    ResetCamera(view)
    Render(view)
    SaveScreenshot(png, view, ImageResolution=[1400, 600])
    print(f"picture (T_C at t = {view.ViewTime:g} s, displacement x 1000) -> {png} "
          f"in {time.perf_counter() - t0:.2f} s")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    code = main(sys.argv[1], sys.argv[2])
    # Leave without Python's finalisers: under xvfb, VTK's teardown of its GLX context
    # raises an X error (GLXBadContext) after the picture is saved, which turned a good
    # run into exit status 1. Everything is written and flushed by now.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
