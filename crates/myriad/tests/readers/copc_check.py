"""Reads a COPC file with laspy's CopcReader and with copclib, as other tools would, and prints
what they found as one JSON object (for crates/myriad/tests/export.rs).

usage: copc_check.py FILE.copc.laz '[[minx,miny,minz,maxx,maxy,maxz], ...]' [--every K]

--every K (a file too large to read whole here, a billion points): every node's count is summed
from the hierarchy, but only every K-th node's points are read (by both readers), and the whole-file
and per-level queries are left out.
"""
import json
import sys

import numpy as np
import laspy
from laspy.copc import Bounds, load_octree_for_query
import copclib

path, boxes = sys.argv[1], json.loads(sys.argv[2])
every = int(sys.argv[4]) if len(sys.argv) > 4 and sys.argv[3] == "--every" else 1
out = {"every": every}
with laspy.CopcReader.open(path) as r:
    out["header_points"] = r.header.point_count
    out["format"] = r.header.point_format.id
    if every == 1:
        out["all"] = len(r.query())
        levels = []
        while sum(levels) < out["header_points"] and len(levels) < 32:
            levels.append(len(r.query(level=len(levels))))
        out["levels"] = levels
        out["boxes"] = [
            len(r.query(bounds=Bounds(mins=np.array(b[:3]), maxs=np.array(b[3:])))) for b in boxes
        ]
    # Every node as laspy walks the hierarchy pages: its chunk holds its count, inside its cube.
    nodes = load_octree_for_query(r.source, r.copc_info, r.root_page)
    slack = np.asarray(r.header.scales)
    node_points = node_outside = node_bad = node_read = hierarchy_points = 0
    for i, n in enumerate(nodes):
        hierarchy_points += max(n.point_count, 0)
        if n.point_count == 0 or i % every:
            continue
        node_read += 1
        pts = r._fetch_and_decompress_points_of_nodes([n])
        node_bad += int(len(pts) != n.point_count)
        node_points += len(pts)
        xyz = np.stack([np.asarray(pts.x), np.asarray(pts.y), np.asarray(pts.z)], axis=1)
        out_of = (xyz < n.bounds.mins - slack) | (xyz > n.bounds.maxs + slack)
        node_outside += int(np.count_nonzero(out_of.any(axis=1)))
    out["laspy_nodes"] = len(nodes)
    out["laspy_nodes_read"] = node_read
    out["laspy_hierarchy_points"] = hierarchy_points
    out["laspy_node_points"] = node_points
    out["laspy_bad_counts"] = node_bad
    out["laspy_outside"] = node_outside
    wkt = [v for v in r.header.vlrs if v.user_id == "LASF_Projection" and v.record_id == 2112]
    out["wkt"] = bool(wkt) and r.header.global_encoding.wkt

reader = copclib.FileReader(path)
info = reader.copc_config.copc_info
scale = reader.copc_config.las_header.scale
half = info.halfsize
nodes = reader.GetAllNodes()
points = outside = bad_counts = read = hierarchy = 0
for i, n in enumerate(nodes):
    hierarchy += n.point_count
    if i % every:
        continue
    read += 1
    pts = reader.GetPoints(n)
    if len(pts) != n.point_count:
        bad_counts += 1
    points += len(pts)
    side = 2 * half / (1 << n.key.d)
    lo = [
        info.center_x - half + n.key.x * side,
        info.center_y - half + n.key.y * side,
        info.center_z - half + n.key.z * side,
    ]
    for axis, (coords, s) in enumerate(zip((pts.x, pts.y, pts.z), (scale.x, scale.y, scale.z))):
        c = np.asarray(coords)
        outside += int(np.count_nonzero((c < lo[axis] - s) | (c > lo[axis] + side + s)))
out["copclib_nodes"] = len(nodes)
out["copclib_nodes_read"] = read
out["copclib_hierarchy_points"] = hierarchy
out["copclib_points"] = points
out["copclib_bad_counts"] = bad_counts
out["copclib_outside"] = outside
print(json.dumps(out))
