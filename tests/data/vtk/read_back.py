"""Reads caveflow's VTK export with VTK's own XML readers (those ParaView uses) and checks
each file's point and cell counts and field names against what the Rust test expects.

usage: read_back.py VTK_DIR EXPECT_JSON

EXPECT_JSON maps a file (relative to VTK_DIR) to [points, cells, point fields, cell fields].
The .pvd collections are checked too: periods ascending, every file listed is expected.
Any error or warning VTK prints fails the check. Run by tests/it/vtk.rs where .ci/run has
made its venv (CAVEFLOW_PY).
"""

import json
import os
import sys
import xml.etree.ElementTree as ET

from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader, vtkXMLRectilinearGridReader

VTK_DOUBLE = 11


def main(root, spec):
    log = vtkStringOutputWindow()
    vtkOutputWindow.SetInstance(log)
    expect = json.load(open(spec))
    problems = []
    for rel, (points, cells, point_fields, cell_fields) in sorted(expect.items()):
        path = os.path.join(root, rel)
        reader = vtkXMLPolyDataReader() if rel.endswith(".vtp") else vtkXMLRectilinearGridReader()
        reader.SetFileName(path)
        reader.Update()
        data = reader.GetOutput()
        got = [
            data.GetNumberOfPoints(),
            data.GetNumberOfCells(),
            [data.GetPointData().GetArrayName(i) for i in range(data.GetPointData().GetNumberOfArrays())],
            [data.GetCellData().GetArrayName(i) for i in range(data.GetCellData().GetNumberOfArrays())],
        ]
        if got != [points, cells, point_fields, cell_fields]:
            problems.append(f"{rel}: read {got}, expected {[points, cells, point_fields, cell_fields]}")
        if rel.endswith(".vtp") and data.GetPoints().GetDataType() != VTK_DOUBLE:
            problems.append(f"{rel}: points are not Float64")
        print(f"{rel}: {got[0]} points, {got[1]} cells")
    for pvd in ("imz.pvd", "markers.pvd", "surface.pvd"):
        sets = ET.parse(os.path.join(root, pvd)).getroot().find("Collection").findall("DataSet")
        steps = [int(s.get("timestep")) for s in sets]
        if not steps or steps != sorted(steps):
            problems.append(f"{pvd}: timesteps {steps}")
        for s in sets:
            if s.get("file") not in expect:
                problems.append(f"{pvd}: lists {s.get('file')}, not an expected file")
        print(f"{pvd}: periods {steps}")
    said = log.GetOutput().strip()
    if said:
        problems.append(f"VTK said: {said}")
    if problems:
        print("\n".join(problems))
        sys.exit(1)
    print(f"{len(expect)} files read")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
