#!/usr/bin/env python3
"""Writes the hostile glTF seeds of the `avatar` fuzz target (fuzz/corpus/SOURCE.md).

Usage: tools/hostile_gltf.py OUT_DIR [CHAIN_NODES]. Each file is a GLB of one triangle with one
fault: a node its own child, a cycle, a node listed twice (2^39 paths), two parents, a deep
chain, accessors and views out of range, a huge count; `ok.glb` has none.
"""
import json, struct, sys
def glb(doc, bin_=b""):
    j = json.dumps(doc, separators=(",", ":")).encode()
    while len(j) % 4: j += b" "
    while len(bin_) % 4: bin_ += b"\0"
    chunks = struct.pack("<I4s", len(j), b"JSON") + j
    if bin_: chunks += struct.pack("<I4s", len(bin_), b"BIN\0") + bin_
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks
# One triangle.
pos = struct.pack("<9f", 0,0,0, 1,0,0, 0,1,0)
def base(nodes, scene_nodes, accessors=None, meshes=None):
    return {"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":scene_nodes}],"nodes":nodes,
      "meshes": meshes or [{"primitives":[{"attributes":{"POSITION":0}}]}],
      "buffers":[{"byteLength":len(pos)}],
      "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":len(pos)}],
      "accessors": accessors or [{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]}
out = {}
out["ok"] = glb(base([{"mesh":0}],[0]), pos)
out["self_child"] = glb(base([{"mesh":0,"children":[0]}],[0]), pos)
n = int(sys.argv[2]) if len(sys.argv) > 2 else 300
out["deep_chain"] = glb(base([{"mesh":0,"children":[1]}]+[{"children":[k+1]} for k in range(1,n-1)]+[{"mesh":0}],[0]), pos)
out["diamond"] = glb(base([{"mesh":0,"children":[k+1,k+1]} for k in range(39)]+[{"mesh":0}],[0]), pos)
out["accessor_oob"] = glb(base([{"mesh":0}],[0], meshes=[{"primitives":[{"attributes":{"POSITION":7}}]}]), pos)
out["indices_oob"] = glb(base([{"mesh":0}],[0], meshes=[{"primitives":[{"attributes":{"POSITION":0},"indices":9}]}]), pos)
out["view_oob"] = glb(base([{"mesh":0}],[0], accessors=[{"bufferView":5,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]), pos)
out["count_huge"] = glb(base([{"mesh":0}],[0], accessors=[{"bufferView":0,"componentType":5126,"count":4000000000,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]), pos)
out["scene_oob"] = glb(dict(base([{"mesh":0}],[0]), scene=4), pos)
out["scene_node_oob"] = glb(base([{"mesh":0}],[3]), pos)
out["mesh_oob"] = glb(base([{"mesh":6}],[0]), pos)
out["child_oob"] = glb(base([{"mesh":0,"children":[8]}],[0]), pos)
out["two_parents"] = glb(base([{"mesh":0,"children":[2]},{"children":[2]},{"mesh":0}],[0,1]), pos)
out["cycle"] = glb(base([{"mesh":0,"children":[1]},{"children":[0]}],[0]), pos)
out["sparse_oob"] = glb(base([{"mesh":0}],[0], accessors=[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0],"sparse":{"count":1,"indices":{"bufferView":0,"componentType":5125,"byteOffset":0},"values":{"bufferView":0}}}]), pos)
for k, v in out.items():
    open(f"{sys.argv[1]}/{k}.glb", "wb").write(v)
