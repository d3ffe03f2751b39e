#!/usr/bin/env python3
"""Writes the avatar test fixtures (tests/data/avatar/SOURCE.md, tests/data/vrm/SOURCE.md).

Usage: tools/make_avatar_fixture.py [REPO_ROOT]. Standard library only; deterministic output.

- tests/data/avatar/ict_multimesh.glb: ICT-FaceKit's neutral head (configs/meshes/ict-facekit, MIT)
  cut into an avatar of four meshes: `Head` (M_Face and M_BackHead: two primitives sharing one
  vertex list, vertex colours, planar UVs with a 4x4 PNG texture, skinned to a root-neck-head
  skeleton, morph targets jawOpen and eyeBlink_L with targetNames), `Eyes` (sclera and iris,
  left and right: four primitives on one vertex list), `Teeth`, and `EyeLashes` (lashes and eye
  occlusion alpha BLEND, lacrimal fluid alpha MASK); the rigid meshes hang under the head joint.
  Units: ICT's centimetres as metres.
- tests/data/vrm/mimic_vrm0.vrm and mimic_vrm1.vrm: a small VRM 0.x and VRM 1.0 of our own (a
  six-triangle face with morph targets blink and aa, bones hips-neck-head plus both eyes,
  expressions blink, aa and, in 1.0, a custom mouthSmileLeft, look-at, an unknown extension).
"""
import json, math, os, struct, sys, zlib

ROOT = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
ICT = os.path.join(ROOT, "configs/meshes/ict-facekit")


class Glb:
    """A GLB being built: one buffer, views and accessors appended."""

    def __init__(self):
        self.bin = bytearray()
        self.views, self.accessors = [], []

    def view(self, data, target=None):
        while len(self.bin) % 4:
            self.bin += b"\0"
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target:
            v["target"] = target
        self.bin += data
        self.views.append(v)
        return len(self.views) - 1

    def accessor(self, fmt, ctype, type_, rows, normalized=False, minmax=False, target=34962):
        data = b"".join(struct.pack("<" + fmt, *r) for r in rows)
        a = {"bufferView": self.view(data, target), "componentType": ctype, "count": len(rows), "type": type_}
        if normalized:
            a["normalized"] = True
        if minmax:
            a["min"] = [min(r[k] for r in rows) for k in range(len(rows[0]))]
            a["max"] = [max(r[k] for r in rows) for k in range(len(rows[0]))]
        self.accessors.append(a)
        return len(self.accessors) - 1

    def vec3(self, rows, minmax=False, target=34962):
        return self.accessor("3f", 5126, "VEC3", rows, minmax=minmax, target=target)

    def indices(self, tris, n):
        flat = [(i,) for t in tris for i in t]
        return self.accessor("H" if n < 65536 else "I", 5123 if n < 65536 else 5125, "SCALAR", flat, target=34963)

    def write(self, doc, path):
        doc["buffers"] = [{"byteLength": len(self.bin)}]
        doc["bufferViews"], doc["accessors"] = self.views, self.accessors
        j = json.dumps(doc, separators=(",", ":")).encode()
        while len(j) % 4:
            j += b" "
        b = bytes(self.bin)
        while len(b) % 4:
            b += b"\0"
        chunks = struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", len(b), b"BIN\0") + b
        with open(path, "wb") as f:
            f.write(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
        print(path, 12 + len(chunks), "bytes")


def png(w, h, rgb):
    """An RGB PNG of w x h pixels from a function (x, y) -> (r, g, b) bytes."""
    raw = b"".join(b"\0" + bytes(c for x in range(w) for c in rgb(x, y)) for y in range(h))
    def chunk(k, d):
        return struct.pack(">I", len(d)) + k + d + struct.pack(">I", zlib.crc32(k + d) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def read_obj(path):
    """Positions (cm) and, per usemtl group, triangles (fans of the OBJ's faces)."""
    pos, groups, cur = [], {}, None
    with open(path) as f:
        for line in f:
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                pos.append(tuple(float(x) for x in p[1:4]))
            elif p[0] == "usemtl":
                cur = groups.setdefault(p[1], [])
            elif p[0] == "f":
                ix = [int(t.split("/")[0]) - 1 for t in p[1:]]
                for k in range(1, len(ix) - 1):
                    cur.append((ix[0], ix[k], ix[k + 1]))
    return pos, groups


def compact(groups):
    """One vertex list for several groups: the old index of each new vertex, and the groups' triangles renumbered."""
    new, old = {}, []
    out = []
    for tris in groups:
        t2 = []
        for t in tris:
            for i in t:
                if i not in new:
                    new[i] = len(old)
                    old.append(i)
            t2.append(tuple(new[i] for i in t))
        out.append(t2)
    return old, out


def ict_fixture(out):
    pos, groups = read_obj(os.path.join(ICT, "generic_neutral_mesh.obj"))
    shapes = {n: read_obj(os.path.join(ICT, n + ".obj"))[0] for n in ("jawOpen", "eyeBlink_L")}
    m = lambda p: (p[0] * 0.01, p[1] * 0.01, p[2] * 0.01)  # cm as metres
    g = Glb()
    # Skeleton (world positions, metres): root, neck, head.
    root_w, neck_w, head_w = (0.0, -0.20, -0.02), (0.0, -0.14, -0.02), (0.0, -0.04, 0.0)
    sub = lambda a, b: tuple(x - y for x, y in zip(a, b))
    # The lip landmarks (iBUG 48-67, SOURCE.md of ict-facekit): the lips are redder.
    lips = [5708, 5695, 2081, 0, 4275, 6200, 6213, 6346, 6461, 5518, 5957, 5841, 5702, 5711, 5533, 6216, 6207, 6470, 5517, 5966]
    mouth = tuple(sum(pos[i][k] for i in lips) / len(lips) for k in range(3))
    # Head: face and back of the head share one vertex list.
    old, (face, back) = compact([groups["M_Face"], groups["M_BackHead"]])
    P = [m(pos[i]) for i in old]
    colors, joints, weights, uvs = [], [], [], []
    for i in old:
        d = math.dist(pos[i], mouth)
        red = max(0.0, 1.0 - d / 3.0)
        colors.append(tuple(round(255 * c) for c in (0.86 + 0.1 * red, 0.66 - 0.3 * red, 0.56 - 0.25 * red, 1.0)))
        y = pos[i][1] * 0.01
        t = min(1.0, max(0.0, (y - neck_w[1]) / (head_w[1] - neck_w[1])))
        # Zero-weight slots name joint 0 (the validator's rule).
        joints.append((1, 2, 0, 0) if 0 < t < 1 else (2 if t >= 1 else 1, 0, 0, 0))
        weights.append((1.0 - t, t, 0.0, 0.0) if 0 < t < 1 else (1.0, 0.0, 0.0, 0.0))
        uvs.append(((pos[i][0] + 12.5) / 25.0, (14.5 - pos[i][1]) / 34.0))
    head_attr = {
        "POSITION": g.vec3(P, minmax=True),
        "TEXCOORD_0": g.accessor("2f", 5126, "VEC2", uvs),
        "COLOR_0": g.accessor("4B", 5121, "VEC4", colors, normalized=True),
        "JOINTS_0": g.accessor("4B", 5121, "VEC4", joints),
        "WEIGHTS_0": g.accessor("4f", 5126, "VEC4", weights),
    }
    targets = [{"POSITION": g.vec3([m(sub(shapes[n][i], pos[i])) for i in old], minmax=True)} for n in ("jawOpen", "eyeBlink_L")]
    head_prims = [
        {"attributes": head_attr, "indices": g.indices(tris, len(P)), "material": mat, "targets": targets}
        for tris, mat in ((face, 0), (back, 1))
    ]
    # Rigid parts under the head joint: positions in the head joint's space.
    def rigid(names, mats):
        old, tris = compact([groups[n] for n in names])
        P = [sub(m(pos[i]), head_w) for i in old]
        a = g.vec3(P, minmax=True)
        return [{"attributes": {"POSITION": a}, "indices": g.indices(t, len(P)), "material": mat} for t, mat in zip(tris, mats)]
    eyes = rigid(["M_ScleraLeft", "M_IrisLeft", "M_ScleraRight", "M_IrisRight"], [2, 3, 4, 5])
    teeth = rigid(["M_Teeth"], [6])
    lashes = rigid(["M_EyeLashes", "M_EyeOcclusion", "M_LacrimalFluid"], [7, 8, 9])
    # Inverse bind matrices: joints at their world positions, unrotated.
    ibm = [(1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -w[0], -w[1], -w[2], 1) for w in (root_w, neck_w, head_w)]
    ibm_acc = g.accessor("16f", 5126, "MAT4", ibm, target=None)
    tex = png(4, 4, lambda x, y: (200 + 10 * x, 160 + 10 * y, 140))
    img_view = g.view(tex)
    def mat(name, rgba, **kw):
        d = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(rgba), "metallicFactor": 0.0, "roughnessFactor": 0.8}}
        d.update(kw)
        return d
    face_mat = mat("M_Face", (1, 1, 1, 1))
    face_mat["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
    doc = {
        "asset": {"version": "2.0", "generator": "mimic tools/make_avatar_fixture.py (ICT-FaceKit, MIT)"},
        "scene": 0,
        "scenes": [{"name": "Scene", "nodes": [0, 4]}],
        "nodes": [
            {"name": "Avatar", "children": [1]},
            {"name": "root", "translation": list(root_w), "children": [2]},
            {"name": "neck", "translation": list(sub(neck_w, root_w)), "children": [3]},
            {"name": "head", "translation": list(sub(head_w, neck_w)), "children": [5, 6, 7]},
            {"name": "Head", "mesh": 0, "skin": 0},
            {"name": "Eyes", "mesh": 1},
            {"name": "Teeth", "mesh": 2},
            {"name": "EyeLashes", "mesh": 3},
        ],
        "meshes": [
            {"name": "Head", "primitives": head_prims, "weights": [0.0, 0.0], "extras": {"targetNames": ["jawOpen", "eyeBlink_L"]}},
            {"name": "Eyes", "primitives": eyes},
            {"name": "Teeth", "primitives": teeth},
            {"name": "EyeLashes", "primitives": lashes},
        ],
        "skins": [{"name": "Armature", "joints": [1, 2, 3], "inverseBindMatrices": ibm_acc, "skeleton": 1}],
        "materials": [
            face_mat,
            mat("M_BackHead", (0.6, 0.6, 0.6, 1)),
            mat("M_ScleraLeft", (0.95, 0.95, 0.95, 1)),
            mat("M_IrisLeft", (0.25, 0.35, 0.5, 1)),
            mat("M_ScleraRight", (0.95, 0.95, 0.95, 1)),
            mat("M_IrisRight", (0.25, 0.35, 0.5, 1)),
            mat("M_Teeth", (0.92, 0.9, 0.85, 1)),
            mat("M_EyeLashes", (0.05, 0.04, 0.03, 0.9), alphaMode="BLEND", doubleSided=True),
            mat("M_EyeOcclusion", (0.2, 0.15, 0.15, 0.35), alphaMode="BLEND"),
            mat("M_LacrimalFluid", (1, 1, 1, 0.5), alphaMode="MASK", alphaCutoff=0.3),
        ],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 33648, "wrapT": 33071}],
        "textures": [{"name": "skin", "sampler": 0, "source": 0}],
        "images": [{"name": "skin", "bufferView": img_view, "mimeType": "image/png"}],
    }
    g.write(doc, os.path.join(out, "ict_multimesh.glb"))


def vrm(version, path):
    """A small VRM: a six-triangle face (morph targets blink and aa), hips-neck-head and two eyes."""
    g = Glb()
    P = [(0, 1.5, 0.1), (-0.08, 1.6, 0.08), (0.08, 1.6, 0.08), (-0.08, 1.45, 0.08), (0.08, 1.45, 0.08), (0, 1.7, 0.05), (0, 1.38, 0.06)]
    tris = [(0, 1, 3), (0, 4, 2), (0, 2, 1), (0, 3, 4), (1, 2, 5), (3, 6, 4)]
    blink = [(0, 0, 0), (0, -0.01, 0), (0, -0.01, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0)]
    aa = [(0, 0, 0)] * 6 + [(0, -0.03, 0)]
    prim = {"attributes": {"POSITION": g.vec3(P, minmax=True)}, "indices": g.indices(tris, len(P)), "material": 0,
            "targets": [{"POSITION": g.vec3(blink, minmax=True)}, {"POSITION": g.vec3(aa, minmax=True)}]}
    nodes = [
        {"name": "Root", "children": [1, 6]},
        {"name": "J_Bip_C_Hips", "translation": [0, 1.0, 0], "children": [2]},
        {"name": "J_Bip_C_Neck", "translation": [0, 0.4, 0], "children": [3]},
        {"name": "J_Bip_C_Head", "translation": [0, 0.1, 0], "children": [4, 5]},
        {"name": "J_Adj_L_FaceEye", "translation": [0.03, 0.05, 0.06]},
        {"name": "J_Adj_R_FaceEye", "translation": [-0.03, 0.05, 0.06]},
        {"name": "Face", "mesh": 0},
    ]
    doc = {
        "asset": {"version": "2.0", "generator": "mimic tools/make_avatar_fixture.py"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": nodes,
        "meshes": [{"name": "Face", "primitives": [prim], "extras": {"targetNames": ["blink", "aa"]}}],
        "materials": [{"name": "Skin", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.7, 0.6, 1]}}],
        "extensions": {"MIMIC_unknown_test": {"kept": True}},
    }
    bones = {"hips": 1, "neck": 2, "head": 3, "leftEye": 4, "rightEye": 5}
    if version == 0:
        doc["extensionsUsed"] = ["VRM", "MIMIC_unknown_test"]
        doc["extensions"]["VRM"] = {
            "exporterVersion": "mimic-fixture", "specVersion": "0.0",
            "meta": {"title": "mimic VRM 0.x fixture", "author": "mimic", "allowedUserName": "Everyone", "licenseName": "CC0"},
            "humanoid": {"humanBones": [{"bone": b, "node": n, "useDefaultValues": True} for b, n in bones.items()]},
            "blendShapeMaster": {"blendShapeGroups": [
                {"name": "Blink", "presetName": "blink", "binds": [{"mesh": 0, "index": 0, "weight": 100}], "isBinary": False},
                {"name": "A", "presetName": "a", "binds": [{"mesh": 0, "index": 1, "weight": 80}]},
                {"name": "Joy", "presetName": "joy", "binds": []},
            ]},
            "firstPerson": {"firstPersonBone": 3, "firstPersonBoneOffset": {"x": 0, "y": 0.06, "z": 0}, "lookAtTypeName": "Bone",
                            "lookAtHorizontalInner": {"curve": [0, 0, 0, 1, 1, 1, 1, 0], "xRange": 90, "yRange": 8},
                            "lookAtHorizontalOuter": {"curve": [0, 0, 0, 1, 1, 1, 1, 0], "xRange": 90, "yRange": 12},
                            "lookAtVerticalDown": {"curve": [0, 0, 0, 1, 1, 1, 1, 0], "xRange": 90, "yRange": 10},
                            "lookAtVerticalUp": {"curve": [0, 0, 0, 1, 1, 1, 1, 0], "xRange": 90, "yRange": 10}},
        }
    else:
        doc["extensionsUsed"] = ["VRMC_vrm", "MIMIC_unknown_test"]
        doc["extensions"]["VRMC_vrm"] = {
            "specVersion": "1.0",
            "meta": {"name": "mimic VRM 1.0 fixture", "version": "1", "authors": ["mimic"], "licenseUrl": "https://vrm.dev/licenses/1.0/",
                     "avatarPermission": "everyone", "commercialUsage": "corporation", "creditNotation": "unnecessary",
                     "allowRedistribution": True, "modification": "allowModificationRedistribution"},
            "humanoid": {"humanBones": {b: {"node": n} for b, n in bones.items()}},
            "expressions": {
                "preset": {"blink": {"morphTargetBinds": [{"node": 6, "index": 0, "weight": 1.0}], "isBinary": False},
                           "aa": {"morphTargetBinds": [{"node": 6, "index": 1, "weight": 0.8}]},
                           "happy": {}},
                "custom": {"mouthSmileLeft": {"morphTargetBinds": [{"node": 6, "index": 1, "weight": 0.25}]}},
            },
            "lookAt": {"offsetFromHeadBone": [0, 0.06, 0], "type": "bone",
                       "rangeMapHorizontalInner": {"inputMaxValue": 90, "outputScale": 8},
                       "rangeMapHorizontalOuter": {"inputMaxValue": 90, "outputScale": 12},
                       "rangeMapVerticalDown": {"inputMaxValue": 90, "outputScale": 10},
                       "rangeMapVerticalUp": {"inputMaxValue": 90, "outputScale": 10}},
        }
    g.write(doc, path)


if __name__ == "__main__":
    ict_fixture(os.path.join(ROOT, "tests/data/avatar"))
    vrm(0, os.path.join(ROOT, "tests/data/vrm/mimic_vrm0.vrm"))
    vrm(1, os.path.join(ROOT, "tests/data/vrm/mimic_vrm1.vrm"))
