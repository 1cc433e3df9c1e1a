"""Reads a 3D Tiles export with py3dtiles: every tileset file (external ones included) and
every tile's content, with the points' Earth-centred positions as the 3D Tiles conventions
place them (the tiles' transforms, RTC_CENTER for .pnts, the glTF node's translation and its
y-up axes for glTF). With an input LAS/LAZ file, compares them with pyproj's transform of the
input's points to EPSG:4978: each coordinate's sorted values side by side (equal sets of points
within d give sorted coordinates within d).

usage: tiles3d_check.py TILESET.json [INPUT.las]; prints one line of JSON.
"""

import json
import sys
from pathlib import Path

import numpy as np
from py3dtiles.tileset.content import Pnts
from py3dtiles.tileset.tileset import TileSet

# glTF's y-up to 3D Tiles' z-up: (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=np.float64)

report = {"tilesets": 0, "tiles": 0, "points": 0, "versions": [], "fields": []}
positions = []


def walk(tileset_path: Path, parent: np.ndarray) -> None:
    tileset = TileSet.from_file(tileset_path)
    report["tilesets"] += 1
    report["versions"].append(tileset.asset.version.value if hasattr(tileset.asset.version, "value") else str(tileset.asset.version))

    def tile(t, m: np.ndarray) -> None:
        m = m @ t.transform
        if t.content_uri is not None:
            uri = tileset.root_uri / t.content_uri
            if uri.suffix == ".json":
                walk(uri, m)
            else:
                content = t.get_or_fetch_content(tileset.root_uri)
                xyz = np.asarray(content.get_vertices(), dtype=np.float64).reshape(-1, 3)
                if isinstance(content, Pnts):
                    rtc = content.body.feature_table.header.rtc
                    xyz = xyz + np.asarray(rtc if rtc is not None else [0, 0, 0])
                else:
                    node = content._gltf.nodes[0]
                    xyz = xyz + np.asarray(node.translation or [0, 0, 0])
                    xyz = xyz @ Y_UP_TO_Z_UP.T
                    for f in sorted(content.get_extra_field_names()):
                        if f not in report["fields"]:
                            report["fields"].append(f)
                ecef = xyz @ m[:3, :3].T + m[:3, 3]
                positions.append(ecef)
                report["tiles"] += 1
                report["points"] += len(xyz)
        for c in t.children:
            tile(c, m)

    tile(tileset.root_tile, parent)


walk(Path(sys.argv[1]), np.identity(4))
if len(sys.argv) > 2:
    import laspy
    from pyproj import Transformer

    las = laspy.read(sys.argv[2])
    t = Transformer.from_crs(las.header.parse_crs(), "EPSG:4978", always_xy=True)
    want = np.stack(t.transform(np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)), axis=1)
    got = np.concatenate(positions) if positions else np.zeros((0, 3))
    report["input_points"] = len(want)
    if len(got) == len(want):
        report["worst"] = float(max(np.abs(np.sort(got[:, a]) - np.sort(want[:, a])).max() for a in range(3)))
print(json.dumps(report))
