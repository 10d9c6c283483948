"""Imports a smoke run into Blender as a user would and prints what Blender sees, one JSON
object per line, for tests/blender_import.rs.

Arguments after `--`: the character GLB, the folder of the NAME_NNNN.vdb sequence, the
frame rate. The scene is set to that frame rate before the glTF import (which keys the
animation at seconds x scene fps from frame 0), and the volume sequence starts at frame 0
(Blender's volume import starts it at 1), so frame k shows the character's and the
smoke's k-th frames.

Per frame: the bounds of the fluid (marching cubes of `temperature` > 1e-6, which the
source's warm air fills from the first step), of the hole the character leaves in it (the
same surface's vertices inside the box, away from its walls and its floor layer), of the
smoke column (`density` > 0.5) and of the character's deformed mesh. Blender's mesher puts
surfaces half a voxel off the file's voxel centres; the tests allow a voxel or two.
"""
import json
import os
import sys

import bpy

glb, vdb_dir, fps = sys.argv[sys.argv.index("--") + 1 :][:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps = int(float(fps))
bpy.ops.import_scene.gltf(filepath=glb)
characters = [o for o in scene.objects if o.type == "MESH"]
files = sorted(f for f in os.listdir(vdb_dir) if f.endswith(".vdb"))
bpy.ops.object.volume_import(
    filepath=os.path.join(vdb_dir, files[0]), directory=vdb_dir, files=[{"name": f} for f in files]
)
volume = next(o for o in scene.objects if o.type == "VOLUME")
volume.data.frame_start = 0
volume.data.grids.load()
grids = {g.name: g.data_type for g in volume.data.grids}
print(json.dumps({"grids": grids, "sequence": volume.data.is_sequence, "frames": volume.data.frame_duration}))


def surface(grid, threshold):
    """World positions of the marching-cubes surface of `grid` at `threshold`, this frame."""
    mesh = bpy.data.meshes.new("iso")
    probe = bpy.data.objects.new("iso", mesh)
    scene.collection.objects.link(probe)
    modifier = probe.modifiers.new("to_mesh", "VOLUME_TO_MESH")
    modifier.object = volume
    modifier.grid_name = grid
    modifier.threshold = threshold
    modifier.resolution_mode = "GRID"
    evaluated = probe.evaluated_get(bpy.context.evaluated_depsgraph_get())
    points = [evaluated.matrix_world @ v.co for v in evaluated.to_mesh().vertices]
    evaluated.to_mesh_clear()
    bpy.data.objects.remove(probe)
    bpy.data.meshes.remove(mesh)
    return points


def bounds(points):
    if not points:
        return None
    return [[min(p[a] for p in points) for a in range(3)], [max(p[a] for p in points) for a in range(3)]]


for frame in range(int(volume.data.frame_duration)):
    scene.frame_set(frame)
    fluid = surface("temperature", 1e-6)
    box = bounds(fluid)
    hole = None
    if box:
        lo, hi = box
        inside = [
            p for p in fluid if all(lo[a] + 0.25 < p[a] < hi[a] - 0.25 for a in range(2)) and lo[2] + 0.15 < p[2] < hi[2] - 0.25
        ]
        hole = bounds(inside)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    body = []
    for c in characters:
        evaluated = c.evaluated_get(depsgraph)
        body += [evaluated.matrix_world @ v.co for v in evaluated.to_mesh().vertices]
        evaluated.to_mesh_clear()
    print(
        json.dumps(
            {
                "frame": frame,
                "fluid": box,
                "hole": hole,
                "column": bounds(surface("density", 0.5)),
                "character": bounds(body),
            }
        )
    )
