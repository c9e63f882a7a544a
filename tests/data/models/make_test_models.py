#!/usr/bin/env python3
"""Writes the small test models used by tests/render/mesh_test.cpp (run from anywhere; the files are
committed, this script documents how they were made). Pure standard library."""
import base64
import json
import os
import random
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def write(name, data):
    mode = "wb" if isinstance(data, (bytes, bytearray)) else "w"
    with open(os.path.join(HERE, name), mode) as f:
        f.write(data)


def png(rows):
    """rows: list of lists of (r, g, b). Returns PNG bytes (8-bit RGB)."""
    h, w = len(rows), len(rows[0])
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


RED, GREEN, BLUE, WHITE = (255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 255)
# 4x4 quadrants: top-left red, top-right green, bottom-left blue, bottom-right white.
QUADRANTS = png([[RED, RED, GREEN, GREEN]] * 2 + [[BLUE, BLUE, WHITE, WHITE]] * 2)


def box(lo, hi):
    """Flat-faced box, 24 vertices, CCW seen from outside. Returns positions, normals, uvs, indices."""
    P, N, T, I = [], [], [], []
    for axis in range(3):
        for sign in (-1, 1):
            u_ax, v_ax = [a for a in range(3) if a != axis]
            # corners in (u, v) order CCW seen from outside along +axis when (u, v, axis) is right-handed
            quad = [(0, 0), (1, 0), (1, 1), (0, 1)]
            right_handed = (u_ax, v_ax, axis) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)]
            if right_handed != (sign > 0):
                quad = quad[::-1]
            base = len(P)
            for (a, b) in quad:
                p = [0.0, 0.0, 0.0]
                p[axis] = hi[axis] if sign > 0 else lo[axis]
                p[u_ax] = hi[u_ax] if a else lo[u_ax]
                p[v_ax] = hi[v_ax] if b else lo[v_ax]
                n = [0.0, 0.0, 0.0]
                n[axis] = float(sign)
                P.append(p), N.append(n), T.append([float(a), float(b)])
            I += [base, base + 1, base + 2, base, base + 2, base + 3]
    return P, N, T, I


def pack(fmt, rows):
    return b"".join(struct.pack("<" + fmt, *r) if isinstance(r, (list, tuple)) else struct.pack("<" + fmt, r)
                    for r in rows)


class GltfBuilder:
    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0"}, "bufferViews": [], "accessors": [], "meshes": []}

    def view(self, data, target=None):
        while len(self.bin) % 4:
            self.bin += b"\x00"
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target:
            v["target"] = target
        self.bin += data
        self.doc["bufferViews"].append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, data, ctype, type_, count, target=None, **extra):
        a = {"bufferView": self.view(data, target), "componentType": ctype, "type": type_, "count": count}
        a.update(extra)
        self.doc["accessors"].append(a)
        return len(self.doc["accessors"]) - 1

    def positions(self, P):
        lo = [min(p[i] for p in P) for i in range(3)]
        hi = [max(p[i] for p in P) for i in range(3)]
        return self.accessor(pack("3f", P), 5126, "VEC3", len(P), 34962, min=lo, max=hi)

    def finish_embedded(self):
        self.doc["buffers"] = [{"byteLength": len(self.bin),
                                "uri": "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()}]
        return json.dumps(self.doc, indent=1)

    def finish_glb(self):
        while len(self.bin) % 4:
            self.bin += b"\x00"
        self.doc["buffers"] = [{"byteLength": len(self.bin)}]
        js = json.dumps(self.doc).encode()
        while len(js) % 4:
            js += b" "
        body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(self.bin), b"BIN\x00") + self.bin
        return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def box_gltf():
    # Box x [0,1], y [0,0.5], z [-0.5,0.5] in glTF axes; two nodes (matrix parent, TRS child) move it
    # to z [1.5, 2.5] and rotate it 180 deg about z. Scene 1 (not the default) holds a far-away copy.
    g = GltfBuilder()
    P, N, T, I = box([0, 0, -0.5], [1, 0.5, 0.5])
    pos = g.positions(P)
    uv = g.accessor(pack("2f", T), 5126, "VEC2", len(T), 34962)
    idx = g.accessor(pack("H", I), 5123, "SCALAR", len(I), 34963)
    g.doc["meshes"] = [{"name": "box", "primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv},
                                                        "indices": idx, "material": 0}]}]
    g.doc["materials"] = [{"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1.0],
                                                                      "baseColorTexture": {"index": 0}}}]
    g.doc["textures"] = [{"source": 0}]
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(QUADRANTS).decode()}]
    g.doc["nodes"] = [
        {"name": "parent", "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1], "children": [1]},
        {"name": "child", "translation": [0, 0, 1], "rotation": [0, 0, 1, 0], "mesh": 0},
        {"name": "elsewhere", "translation": [100, 0, 0], "mesh": 0},
    ]
    g.doc["scenes"] = [{"nodes": [0]}, {"nodes": [2]}]
    g.doc["scene"] = 0
    return g


def box_glb():
    # Box (with NORMAL, u32 indices, PNG in a bufferView) scaled by 2, plus a one-triangle mesh with
    # u8 indices moved up 3 m: two meshes, one primitive each.
    g = GltfBuilder()
    P, N, T, I = box([0, 0, -0.5], [1, 0.5, 0.5])
    pos = g.positions(P)
    nrm = g.accessor(pack("3f", N), 5126, "VEC3", len(N), 34962)
    uv = g.accessor(pack("2f", T), 5126, "VEC2", len(T), 34962)
    idx = g.accessor(pack("I", I), 5125, "SCALAR", len(I), 34963)
    tri_pos = g.positions([[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    tri_idx = g.accessor(pack("B", [0, 1, 2]) + b"\x00", 5121, "SCALAR", 3, 34963)
    img_view = g.view(QUADRANTS)
    g.doc["meshes"] = [
        {"name": "box", "primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv},
                                        "indices": idx, "material": 0}]},
        {"name": "tri", "primitives": [{"attributes": {"POSITION": tri_pos}, "indices": tri_idx}]},
    ]
    g.doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    g.doc["textures"] = [{"source": 0}]
    g.doc["images"] = [{"bufferView": img_view, "mimeType": "image/png"}]
    g.doc["nodes"] = [{"mesh": 0, "scale": [2, 2, 2]}, {"mesh": 1, "translation": [0, 3, 0]}]
    g.doc["scenes"] = [{"nodes": [0, 1]}]
    return g


def triangle_gltf(mode=None, indices=(0, 1, 2), positions=((0, 0, 0), (1, 0, 0), (0, 1, 0)), attr="POSITION",
                  count=None):
    g = GltfBuilder()
    pos = g.accessor(pack("3f", positions), 5126, "VEC3", count or len(positions), 34962)
    idx = g.accessor(pack("H", list(indices)), 5123, "SCALAR", len(indices), 34963)
    prim = {"attributes": {attr: pos}, "indices": idx}
    if mode is not None:
        prim["mode"] = mode
    g.doc["meshes"] = [{"name": "tri", "primitives": [prim]}]
    g.doc["nodes"] = [{"mesh": 0}]
    g.doc["scenes"] = [{"nodes": [0]}]
    return g


def main():
    write("checker.png", QUADRANTS)
    write("box.gltf", box_gltf().finish_embedded())
    glb = box_glb().finish_glb()
    write("box.glb", glb)

    # OBJ in centimetres with OpenGL-style axes (-z forward, +x right, +y up): a textured quad and a
    # plain triangle in two materials.
    write("textured.mtl", "newmtl painted\nKd 1 1 1\nmap_Kd checker.png\n\nnewmtl plain\nKd 0.1 0.5 0.9\n")
    write("textured.obj", "mtllib textured.mtl\n"
          "v 0 0 -100\nv 100 0 -100\nv 100 50 -100\nv 0 50 -100\n"
          "v 0 0 0\nv 100 0 0\nv 0 100 0\n"
          "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
          "o quad\nusemtl painted\nf 1/1 2/2 3/3 4/4\n"
          "o tri\nusemtl plain\nf 5 6 7\n")

    # ---- Broken files: each must give an Error naming the file, never a crash.
    write("broken_truncated.glb", glb[: len(glb) // 2])
    write("broken_text.glb", "this is a text file, not a binary glTF\n")
    rnd = random.Random(1234)
    write("broken_random.glb", bytes(rnd.randrange(256) for _ in range(777)))
    write("broken_random.gltf", bytes(rnd.randrange(256) for _ in range(777)))
    write("broken_random.obj", bytes(rnd.randrange(256) for _ in range(777)))
    write("broken_empty.gltf", "")
    write("broken_empty.glb", b"")
    write("broken_empty.obj", "")
    write("broken_json.gltf", '{"asset": {"version": "2.0"}, "meshes": [{"primitives": [')
    write("broken_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    write("broken_no_faces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    write("broken_missing_texture.mtl", "newmtl m\nKd 1 1 1\nmap_Kd not_there.png\n")
    write("broken_missing_texture.obj", "mtllib broken_missing_texture.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
          "vt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n")
    write("broken_index.gltf", triangle_gltf(indices=(0, 1, 5)).finish_embedded())
    write("broken_lines.gltf", triangle_gltf(mode=1, indices=(0, 1, 1, 2)).finish_embedded())
    write("broken_nan.gltf", triangle_gltf(positions=((0, 0, 0), (float("nan"), 0, 0), (0, 1, 0))).finish_embedded())
    write("broken_accessor.gltf", triangle_gltf(count=1000).finish_embedded())
    write("broken_no_position.gltf", triangle_gltf(attr="NORMAL").finish_embedded())
    g = triangle_gltf()
    g.doc["nodes"] = [{"mesh": 0, "children": [1]}, {"children": [0]}]
    write("broken_cycle.gltf", g.finish_embedded())
    g = triangle_gltf()
    g.finish_embedded()
    g.doc["buffers"][0]["uri"] = "not_there.bin"
    write("broken_missing_buffer.gltf", json.dumps(g.doc))
    write("broken_unknown.stl", "solid x\nendsolid x\n")


if __name__ == "__main__":
    main()
