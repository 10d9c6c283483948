#!/usr/bin/env python3
"""Writes the hand-made glTF seeds of the gltf_loader fuzz target.

One tiny scene: a two-joint skin (root at 1 m, child 0.5 m above it), one skinned
triangle, and one animation rotating the child about Z over one second (linear, three
keys) plus a step translation of the root. Emitted three ways:
  tri_skin_anim.gltf      JSON with the buffer as a base64 data URI
  tri_skin_anim.json_bin  JSON without buffer URI, a NUL, then the buffer bytes (the
                          target wraps this into a GLB: see gltf_loader.rs)
  tri_skin_anim.glb       a real GLB container
plus minimal.gltf, the smallest valid document.
Run from anywhere: python3 fuzz/tools/make_gltf_seeds.py
"""
import base64
import json
import math
import os
import struct
import zlib

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "seeds", "gltf_loader")


def f32(*values):
    return struct.pack("<%df" % len(values), *values)


def pad4(b, fill=b"\0"):
    return b + fill * ((4 - len(b) % 4) % 4)


views = []  # (offset, length)
buf = b""


def add_view(data):
    global buf
    buf = pad4(buf)
    views.append((len(buf), len(data)))
    buf += data
    return len(views) - 1


positions = [(0.0, 1.0, 0.0), (0.2, 1.6, 0.0), (-0.2, 1.6, 0.0)]
v_pos = add_view(f32(*[c for p in positions for c in p]))
v_idx = add_view(struct.pack("<3H", 0, 1, 2))
v_joints = add_view(bytes([0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]))
v_weights = add_view(f32(0.5, 0.5, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0))
# Inverse bind matrices (column-major): root at y=1, child at y=1.5.
ibm = f32(1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1.0, 0, 1) + f32(1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1.5, 0, 1)
v_ibm = add_view(ibm)
times = [0.0, 0.5, 1.0]
v_times = add_view(f32(*times))
quats = []
for angle in (0.0, 0.4, 0.8):
    quats += [0.0, 0.0, math.sin(angle / 2), math.cos(angle / 2)]
v_rot = add_view(f32(*quats))
v_step_times = add_view(f32(0.0, 1.0))
v_step = add_view(f32(0.0, 1.0, 0.0, 0.1, 1.0, 0.0))
buf = pad4(buf)


def accessor(view, count, type_, ctype=5126, **extra):
    a = {"bufferView": view, "componentType": ctype, "count": count, "type": type_}
    a.update(extra)
    return a


doc = {
    "asset": {"version": "2.0", "generator": "kinegraph fuzz seed (hand-made)"},
    "scene": 0,
    "scenes": [{"nodes": [0, 2]}],
    "nodes": [
        {"name": "root", "translation": [0, 1, 0], "children": [1]},
        {"name": "child", "translation": [0, 0.5, 0]},
        {"name": "body", "mesh": 0, "skin": 0},
    ],
    "skins": [{"joints": [0, 1], "inverseBindMatrices": 4}],
    "meshes": [
        {
            "name": "tri",
            "primitives": [
                {"attributes": {"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}, "indices": 1, "mode": 4}
            ],
        }
    ],
    "accessors": [
        accessor(v_pos, 3, "VEC3", min=[-0.2, 1.0, 0.0], max=[0.2, 1.6, 0.0]),
        accessor(v_idx, 3, "SCALAR", 5123),
        accessor(v_joints, 3, "VEC4", 5121),
        accessor(v_weights, 3, "VEC4"),
        accessor(v_ibm, 2, "MAT4"),
        accessor(v_times, 3, "SCALAR", min=[0.0], max=[1.0]),
        accessor(v_rot, 3, "VEC4"),
        accessor(v_step_times, 2, "SCALAR", min=[0.0], max=[1.0]),
        accessor(v_step, 2, "VEC3"),
    ],
    "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
    "buffers": [{"byteLength": len(buf)}],
    "animations": [
        {
            "name": "bend",
            "samplers": [
                {"input": 5, "output": 6, "interpolation": "LINEAR"},
                {"input": 7, "output": 8, "interpolation": "STEP"},
            ],
            "channels": [
                {"sampler": 0, "target": {"node": 1, "path": "rotation"}},
                {"sampler": 1, "target": {"node": 0, "path": "translation"}},
            ],
        }
    ],
}

os.makedirs(OUT, exist_ok=True)
compact = json.dumps(doc, separators=(",", ":")).encode()
with open(os.path.join(OUT, "tri_skin_anim.json_bin"), "wb") as f:
    f.write(compact + b"\0" + buf)

json_chunk = pad4(compact, b" ")
glb = b"glTF" + struct.pack("<II", 2, 12 + 8 + len(json_chunk) + 8 + len(buf))
glb += struct.pack("<I", len(json_chunk)) + b"JSON" + json_chunk
glb += struct.pack("<I", len(buf)) + b"BIN\0" + buf
with open(os.path.join(OUT, "tri_skin_anim.glb"), "wb") as f:
    f.write(glb)

doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(buf).decode()
with open(os.path.join(OUT, "tri_skin_anim.gltf"), "w") as f:
    json.dump(doc, f, indent=1)
    f.write("\n")

with open(os.path.join(OUT, "minimal.gltf"), "w") as f:
    f.write('{"asset":{"version":"2.0"}}\n')

# A textured triangle hanging from a bone: every material slot on one data-URI PNG (1 × 1
# RGB), a sampler, alpha mask, the specular and emissive-strength extensions.
def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


png = b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0))
png += png_chunk(b"IDAT", zlib.compress(b"\x00\xff\x80\x00")) + png_chunk(b"IEND", b"")
tri = b"".join(struct.pack("<f", v) for v in [0, 0, 0, 1, 0, 0, 0, 1, 0]) + struct.pack("<4H", 0, 1, 2, 0)
tri += b"".join(struct.pack("<f", v) for v in [0, 0, 1, 0, 0.25, 0.75])
textured = {
    "asset": {"version": "2.0"},
    "scene": 0,
    "scenes": [{"nodes": [0]}],
    "nodes": [
        {"name": "root", "translation": [0, 1, 0], "children": [1]},
        {"name": "bone", "translation": [0, 1, 0], "children": [2]},
        {"name": "badge", "translation": [0.5, 0, 0], "mesh": 0},
    ],
    "skins": [{"joints": [0, 1]}],
    "meshes": [{"name": "badge", "primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 2}, "indices": 1, "material": 0}]}],
    "materials": [
        {
            "name": "paint",
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 0}},
            "normalTexture": {"index": 0, "scale": 0.5},
            "occlusionTexture": {"index": 0, "strength": 0.5},
            "emissiveTexture": {"index": 0},
            "alphaMode": "MASK",
            "alphaCutoff": 0.3,
            "doubleSided": True,
            "extensions": {
                "KHR_materials_specular": {"specularFactor": 0.5, "specularColorFactor": [1, 0.5, 0.25]},
                "KHR_materials_emissive_strength": {"emissiveStrength": 2},
            },
        }
    ],
    "extensionsUsed": ["KHR_materials_specular", "KHR_materials_emissive_strength"],
    "textures": [{"source": 0, "sampler": 0}],
    "samplers": [{"magFilter": 9728, "minFilter": 9987, "wrapS": 33071, "wrapT": 33648}],
    "images": [{"uri": "data:image/png;base64," + base64.b64encode(png).decode()}],
    "buffers": [{"byteLength": len(tri), "uri": "data:application/octet-stream;base64," + base64.b64encode(tri).decode()}],
    "bufferViews": [
        {"buffer": 0, "byteOffset": 0, "byteLength": 36},
        {"buffer": 0, "byteOffset": 36, "byteLength": 6},
        {"buffer": 0, "byteOffset": 44, "byteLength": 24},
    ],
    "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
        {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"},
    ],
}
with open(os.path.join(OUT, "textured_prop.gltf"), "w") as f:
    json.dump(textured, f, separators=(",", ":"))
