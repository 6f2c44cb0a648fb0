"""Renders the outputs of `mskseg segment --image-export vti` in ParaView, offscreen, into one PNG.

    pvbatch scripts/paraview-overlay.py OUT_DIR PNG [--center X,Y,Z] [--size W,H]

(scripts/viewer-screenshot.sh OUT_DIR PNG finds pvbatch, ParaView's Python modules and a display.) The picture has four
views: axial, coronal and sagittal slices of OUT_DIR/image.vti in grey through the centre of the meshes' bounding box
(or --center, LPS mm), each with the cross-sections of the meshes OUT_DIR/<name>.vtk in the structures' colours, and a
3D view of the three slices with the meshes below the axial slice; a legend names the structures. Names, labels and
colours come from OUT_DIR/labels.tsv, else labels.ctbl. Everything is drawn in the files' own space (LPS, as mskseg
writes them); the slices are shown radiologically (the patient's right on the left; axial seen from the feet).

Placement: ParaView 5.11 reads the direction matrix of image.vti, and its Slice filter, its Slice representation and
ResampleToImage honour it, but its Contour filter on image data does not (it places the contour by origin and spacing
only; on the bundled sample that moves a contour of labels.vti by about 170 mm). So the slices here come from the
Slice filter, the overlay is the meshes' own cross-sections rather than contours of labels.vti, and every slice is
checked to lie within the image's physical bounds (its corners mapped with the direction matrix) before drawing.

Errors (a missing image.vti or meshes, a mesh outside the image, files in different spaces) are one line on stderr
and exit code 1. The PNG is written to a temporary name beside PNG and renamed.
"""

import argparse
import os
import sys

PREFIX = "paraview-overlay: "


def fail(message):
    """Prints one line on stderr and exits with code 1."""
    print(PREFIX + message, file=sys.stderr)
    sys.exit(1)


def parse_numbers(text, option, names, kind):
    """'a,b,...' as len(names) numbers of `kind`, or a one-line error naming the option and the form (e.g. X,Y,Z)."""
    try:
        values = [kind(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != len(names):
        fail("%s: expected %s, got '%s'" % (option, ",".join(names), text))
    return values


def hex_colour(text):
    """'#rrggbb' as (r, g, b) in 0..1."""
    text = text.strip().lstrip("#")
    if len(text) != 6:
        raise ValueError(text)
    return tuple(int(text[i:i + 2], 16) / 255.0 for i in (0, 2, 4))


def read_structures(out_dir):
    """The structures as (label, name, (r, g, b) in 0..1), from labels.tsv (BIDS: index, name, color) or labels.ctbl
    (3D Slicer: value name R G B A), label 0 left out."""
    tsv = os.path.join(out_dir, "labels.tsv")
    ctbl = os.path.join(out_dir, "labels.ctbl")
    structures = []
    if os.path.isfile(tsv):
        with open(tsv, encoding="utf-8") as f:
            rows = [line.rstrip("\n").split("\t") for line in f if line.strip()]
        header = rows[0] if rows else []
        if not all(c in header for c in ("index", "name", "color")):
            fail("%s: expected the columns index, name and color" % tsv)
        col = {c: header.index(c) for c in ("index", "name", "color")}
        for n, row in enumerate(rows[1:], start=2):
            try:
                label = int(row[col["index"]])
                structures.append((label, row[col["name"]], hex_colour(row[col["color"]])))
            except (ValueError, IndexError):
                fail("%s: line %d is not 'index<TAB>name<TAB>#rrggbb'" % (tsv, n))
    elif os.path.isfile(ctbl):
        with open(ctbl, encoding="utf-8") as f:
            for n, line in enumerate(f, start=1):
                fields = line.split()
                if not fields or fields[0].startswith("#"):
                    continue
                try:
                    label = int(fields[0])
                    rgb = tuple(int(v) / 255.0 for v in fields[2:5])
                except (ValueError, IndexError):
                    rgb = ()
                if len(rgb) != 3:
                    fail("%s: line %d is not 'value name R G B A'" % (ctbl, n))
                structures.append((label, fields[1], rgb))
    else:
        fail("%s: no labels.tsv or labels.ctbl (the structures' names and colours)" % out_dir)
    return [s for s in structures if s[0] != 0]


def header_space(mesh_path):
    """The space a legacy VTK mesh's header names (SPACE=LPS or SPACE=RAS); LPS when untagged, as mskseg reads it."""
    with open(mesh_path, "rb") as f:
        f.readline()
        title = f.readline().decode("latin-1")
    return "RAS" if "SPACE=RAS" in title else "LPS"


def main():
    parser = argparse.ArgumentParser(prog="paraview-overlay.py", description=__doc__.split("\n")[0])
    parser.add_argument("out_dir", help="output folder of mskseg segment --image-export vti")
    parser.add_argument("png", help="picture to write")
    parser.add_argument("--center", help="where the three slices cross, X,Y,Z mm in the files' space")
    parser.add_argument("--size", default="1600,1200", help="picture size W,H in pixels (default 1600,1200)")
    args = parser.parse_args()

    out_dir = args.out_dir
    image_path = os.path.join(out_dir, "image.vti")
    if not os.path.isdir(out_dir):
        fail("%s: no such folder" % out_dir)
    if not os.path.isfile(image_path):
        fail("%s: missing (run mskseg segment with --image-export vti)" % image_path)
    size = parse_numbers(args.size, "--size", "WH", int)
    if min(size) < 200 or max(size) > 8000:
        fail("--size: each side must be 200..8000 pixels, got %s" % args.size)
    center = parse_numbers(args.center, "--center", "XYZ", float) if args.center else None

    structures = [s for s in read_structures(out_dir) if os.path.isfile(os.path.join(out_dir, s[1] + ".vtk"))]
    if not structures:
        fail("%s: no meshes (<name>.vtk for a structure of labels.tsv or labels.ctbl)" % out_dir)

    # Imported only once the inputs are known to be there: loading ParaView takes about a second.
    from paraview import servermanager
    from paraview import simple as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_WARNING)

    image = pv.XMLImageDataReader(FileName=[image_path])
    image.UpdatePipeline()
    data = servermanager.Fetch(image)
    if data is None or data.GetNumberOfPoints() == 0 or data.GetPointData().GetScalars() is None:
        fail("%s: not VTK XML image data with point values" % image_path)
    scalars = data.GetPointData().GetScalars().GetName()
    space_array = data.GetFieldData().GetAbstractArray("SPACE")
    image_space = space_array.GetValue(0) if space_array is not None else "LPS"

    # The image's physical bounds: its eight corner voxels mapped by origin + direction * (index * spacing).
    extent = data.GetExtent()
    corners = []
    for i in extent[0:2]:
        for j in extent[2:4]:
            for k in extent[4:6]:
                corners.append([0.0, 0.0, 0.0])
                data.TransformIndexToPhysicalPoint(i, j, k, corners[-1])
    lo = [min(c[a] for c in corners) for a in range(3)]
    hi = [max(c[a] for c in corners) for a in range(3)]
    tolerance = 1e-3 * max(h - l for l, h in zip(lo, hi)) + 1e-6

    meshes = []
    for label, name, rgb in structures:
        path = os.path.join(out_dir, name + ".vtk")
        if header_space(path) != image_space:
            fail("%s: its header says SPACE=%s but image.vti is in %s" % (path, header_space(path), image_space))
        reader = pv.LegacyVTKReader(FileNames=[path])
        reader.UpdatePipeline()
        b = reader.GetDataInformation().GetBounds()
        if reader.GetDataInformation().GetNumberOfPoints() == 0:
            fail("%s: no points" % path)
        if any(b[2 * a] > hi[a] + tolerance or b[2 * a + 1] < lo[a] - tolerance for a in range(3)):
            fail("%s: the mesh lies outside image.vti's physical bounds (not the same space)" % path)
        meshes.append((label, name, rgb, reader, b))

    if center is None:
        center = [0.5 * (min(m[4][2 * a] for m in meshes) + max(m[4][2 * a + 1] for m in meshes)) for a in range(3)]

    # One categorical colour map for every mesh cross-section: the value is the structure's label, the annotation its
    # name, so that the scalar bar is the legend.
    lut = pv.GetColorTransferFunction("structure")
    lut.InterpretValuesAsCategories = 1
    lut.Annotations = [str(v) for s in structures for v in (s[0], s[1])]
    lut.IndexedColors = [c for s in structures for c in s[2]]
    grey = pv.GetColorTransferFunction(scalars)
    grey.ApplyPreset("Grayscale", True)
    low, high = data.GetPointData().GetScalars().GetRange()
    grey.RescaleTransferFunction(low, low + 0.85 * (high - low))  # the brightest 15% saturate, as a viewer's window
    grey.AutomaticRescaleRangeMode = "Never"

    def labelled(source, label):
        """`source` with a point array 'structure' equal to `label` everywhere."""
        return pv.Calculator(Input=source, AttributeType="Point Data", ResultArrayName="structure",
                             Function=str(label))

    def image_slice(axis):
        """The Slice filter's cut of image.vti by the plane through `center` normal to `axis`, checked to lie within
        the image's physical bounds (it does not when the direction matrix is ignored)."""
        normal = [1.0 if a == axis else 0.0 for a in range(3)]
        cut = pv.Slice(Input=image, SliceType="Plane")
        cut.SliceType.Origin = center
        cut.SliceType.Normal = normal
        cut.UpdatePipeline()
        info = cut.GetDataInformation()
        b = info.GetBounds()
        if info.GetNumberOfPoints() == 0:
            fail("the plane %s = %.1f mm misses image.vti (%s)" % (
                "xyz"[axis], center[axis], ", ".join("%s %.1f..%.1f" % ("xyz"[a], lo[a], hi[a]) for a in range(3))))
        if any(b[2 * a] < lo[a] - tolerance or b[2 * a + 1] > hi[a] + tolerance for a in range(3)):
            fail("ParaView placed the slice of image.vti outside its physical bounds (direction matrix not applied)")
        return cut

    def mesh_cut(reader, axis):
        cut = pv.Slice(Input=reader, SliceType="Plane")
        cut.SliceType.Origin = center
        cut.SliceType.Normal = [1.0 if a == axis else 0.0 for a in range(3)]
        return cut

    def show_grey(source, view):
        rep = pv.Show(source, view)
        pv.ColorBy(rep, ("POINTS", scalars))
        rep.LookupTable = grey
        rep.Ambient, rep.Diffuse = 1.0, 0.0  # flat: the slice's grey is the image's value, not shading
        return rep

    def show_structure(source, view, line_width=0.0):
        rep = pv.Show(source, view)
        pv.ColorBy(rep, ("POINTS", "structure"))
        rep.LookupTable = lut
        if line_width:
            rep.LineWidth = line_width
            rep.Ambient, rep.Diffuse = 1.0, 0.0
        return rep

    def caption(view, text, location="Upper Left Corner", position=None, size=14):
        rep = pv.Show(pv.Text(Text=text), view)
        rep.WindowLocation = location
        if position is not None:
            rep.Position = position
        rep.FontSize = size
        rep.Color = [1.0, 1.0, 1.0]
        rep.ShowBorder = "Always"  # draws the text's box: black, over the picture
        rep.BackgroundColor = [0.0, 0.0, 0.0, 1.0]
        rep.BorderColor = [0.0, 0.0, 0.0]

    def side(vector):
        """The anatomical direction an LPS axis vector points to: L, R, P, A, S or I."""
        axis = max(range(3), key=lambda a: abs(vector[a]))
        return ("LR", "PA", "SI")[axis][0 if vector[axis] > 0 else 1]

    # Views: plane normal axis, camera direction (from the camera to the focal point) and view-up, all LPS. Axial from
    # the feet with anterior up, coronal from the front with superior up (the patient's right on the left), sagittal
    # from the patient's left with superior up (anterior on the left).
    planes = [(2, "axial", (0, 0, 1), (0, -1, 0)), (1, "coronal", (0, 1, 0), (0, 0, 1)),
              (0, "sagittal", (-1, 0, 0), (0, 0, 1))]
    views = []
    slices = {}
    for axis, title, direction, up in planes:
        view = pv.CreateRenderView()
        view.OrientationAxesVisibility = 0
        view.Background = [0.0, 0.0, 0.0]
        view.UseColorPaletteForBackground = 0
        cut = image_slice(axis)
        slices[axis] = cut
        show_grey(cut, view)
        for label, name, rgb, reader, _ in meshes:
            outline = mesh_cut(reader, axis)
            outline.UpdatePipeline()
            if outline.GetDataInformation().GetNumberOfPoints() > 0:  # a structure this plane misses is left out
                show_structure(labelled(outline, label), view, line_width=3.0)
        # The part shown: the meshes' bounding box grown by 30%, within the slice's bounds.
        b = cut.GetDataInformation().GetBounds()
        shown = []
        for a in range(3):
            m_lo = min(m[4][2 * a] for m in meshes)
            m_hi = max(m[4][2 * a + 1] for m in meshes)
            grow = 0.15 * (m_hi - m_lo)
            shown += [max(b[2 * a], m_lo - grow), min(b[2 * a + 1], m_hi + grow)]
        focus = [0.5 * (shown[2 * a] + shown[2 * a + 1]) for a in range(3)]
        focus[axis] = center[axis]
        extent_mm = [shown[2 * a + 1] - shown[2 * a] for a in range(3)]
        across = [a for a in range(3) if a != axis]
        vertical = max(across, key=lambda a: abs(up[a]))
        horizontal = [a for a in across if a != vertical][0]
        # Parallel projection fitting that part, with a band at the top for the caption.
        aspect = (size[0] / 2.0) / (size[1] / 2.0)
        scale = 0.5 * max(extent_mm[vertical], extent_mm[horizontal] / aspect) / 0.9
        for a in range(3):
            focus[a] += 0.08 * scale * up[a]
        view.CameraParallelProjection = 1
        view.CameraFocalPoint = focus
        view.CameraPosition = [focus[a] - 1000.0 * direction[a] for a in range(3)]
        view.CameraViewUp = list(up)
        view.CameraParallelScale = scale
        caption(view, "%s  %s = %.1f mm (%s), %s up" % (title, "xyz"[axis], center[axis], image_space, side(up)))
        right = [direction[1] * up[2] - direction[2] * up[1], direction[2] * up[0] - direction[0] * up[2],
                 direction[0] * up[1] - direction[1] * up[0]]
        caption(view, side([-v for v in right]), "Any Location", [0.005, 0.5], 18)
        caption(view, side(right), "Any Location", [0.955, 0.5], 18)
        views.append(view)

    # 3D: the axial slice, and on it each mesh's part above it (clipped by the same plane), seen from the front left
    # and above, so that the meshes' cut ends rest on their cross-sections.
    view3d = pv.CreateRenderView()
    view3d.OrientationAxesVisibility = 1
    view3d.Background = [0.0, 0.0, 0.0]
    view3d.UseColorPaletteForBackground = 0
    show_grey(slices[2], view3d)
    for label, name, rgb, reader, _ in meshes:
        clip = pv.Clip(Input=reader, ClipType="Plane")
        clip.ClipType.Origin = center
        clip.ClipType.Normal = [0.0, 0.0, 1.0]
        clip.Invert = 0  # keep the side the normal points to: superior
        show_structure(labelled(clip, label), view3d)
    camera = view3d.GetActiveCamera()
    camera.SetFocalPoint(center[0], center[1], center[2] + 0.2 * (hi[2] - center[2]))
    camera.SetViewUp(0.0, 0.0, 1.0)
    # From the meshes' size: LPS -y is anterior, +x the patient's left, +z superior.
    distance = 2.2 * max(max(m[4][2 * a + 1] for m in meshes) - min(m[4][2 * a] for m in meshes) for a in range(3))
    camera.SetPosition(center[0] + 0.45 * distance, center[1] - 0.8 * distance, center[2] + 0.5 * distance)
    camera.SetViewAngle(30.0)
    caption(view3d, "3D (%s): axial slice, meshes above it" % image_space)
    bar = pv.GetScalarBar(lut, view3d)
    bar.Title = "structure"
    bar.ComponentTitle = ""
    bar.WindowLocation = "Lower Right Corner"
    bar.TitleFontSize = 16
    bar.LabelFontSize = 16
    bar.Visibility = 1

    layout = pv.CreateLayout("mskseg overlay")
    layout.SplitHorizontal(0, 0.5)
    layout.SplitVertical(1, 0.5)
    layout.SplitVertical(2, 0.5)
    # Cells: 3 top left, 4 bottom left, 5 top right, 6 bottom right.
    for view, cell in zip(views + [view3d], (3, 5, 4, 6)):
        layout.AssignView(cell, view)
    layout.SeparatorWidth = 2
    layout.SeparatorColor = [0.4, 0.4, 0.4]

    png = os.path.abspath(args.png)
    tmp = os.path.join(os.path.dirname(png), ".%s.tmp-%d.png" % (os.path.basename(png), os.getpid()))
    try:
        pv.SaveScreenshot(tmp, layout, ImageResolution=size)
        if not os.path.isfile(tmp) or os.path.getsize(tmp) == 0:
            fail("%s: ParaView wrote no picture" % png)
        os.replace(tmp, png)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


if __name__ == "__main__":
    main()
