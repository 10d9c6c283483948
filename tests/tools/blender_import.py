# Imports each GLB given after `--` into an empty Blender scene and prints what arrived.
# Usage: blender -b --factory-startup --python tests/tools/blender_import.py -- FILE.glb...
# Exits 1 if any file fails to import or brings no armature.
import sys

import bpy

files = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
failed = False
for path in files:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        result = bpy.ops.import_scene.gltf(filepath=path)
    except Exception as e:  # Blender raises RuntimeError with the importer's message
        print(f"{path}: IMPORT FAILED: {e}")
        failed = True
        continue
    armatures = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    bones = sum(len(a.data.bones) for a in armatures)
    actions = [(a.name, tuple(a.frame_range)) for a in bpy.data.actions]
    verts = sum(len(m.data.vertices) for m in meshes)
    faces = sum(len(m.data.polygons) for m in meshes)
    skinned = sum(1 for m in meshes if any(mod.type == "ARMATURE" for mod in m.modifiers))
    # Object names joined by '|', spaces as %20, so the line stays one field per key.
    names = "|".join(sorted(m.name for m in meshes)).replace(" ", "%20")
    print(f"{path}: {result}, armatures={len(armatures)} bones={bones} meshes={len(meshes)} mesh_names={names} "
          f"skinned={skinned} vertices={verts} faces={faces} materials={len(bpy.data.materials)} "
          f"images={len(bpy.data.images)} actions={actions}")
    if not armatures:
        failed = True
sys.exit(1 if failed else 0)
