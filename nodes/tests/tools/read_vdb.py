"""Independent reader for the VDB export tests: OpenVDB's own Python bindings
(Debian's python3-openvdb) read a .vdb file and print every grid's active voxels as JSON:
{name: {"type", "voxel_size", "background", "voxels": [[i, j, k, value...], ...]}}."""
import json
import sys

import pyopenvdb as vdb

grids, _file_meta = vdb.readAll(sys.argv[1])
out = {}
for g in grids:
    voxels = []
    for item in g.citerOnValues():
        if item.count != 1:
            raise SystemExit(f"{g.name}: unexpected active tile at {item.min}")
        value = item.value
        values = list(value) if isinstance(value, tuple) else [value]
        voxels.append(list(item.min) + values)
    background = g.background
    out[g.name] = {
        "type": g.valueTypeName,
        "voxel_size": list(g.transform.voxelSize()),
        "background": list(background) if isinstance(background, tuple) else [background],
        "voxels": voxels,
    }
json.dump(out, sys.stdout)
