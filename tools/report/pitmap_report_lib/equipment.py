# SPDX-License-Identifier: MIT
"""Equipment models for the report's 3D view (pitmap-report --equipment FILE): glTF binaries
of the mining vehicle, a launch vessel, ... placed at a position and heading in the scene
beside the mesh, as the seed paper's VR scene shows the mining vehicle in the pit.

The file (YAML):

    equipment:
      - name: mining vehicle        # shown in the view
        model: crawler.glb          # glTF 2.0 binary; a relative path is from this file
        easting: 603412.0           # in the products' UTM zone (summary.json utm_epsg), m
        northing: 4477697.0
        heading_deg: 45             # clockwise from grid north; the model's front is glTF +Z
        height: null                # m in the products' vertical datum; null or absent: on
                                    # the surface under it (the mesh), else the water

Every problem of the file is listed at once (EquipmentError); a model is checked to be a glTF
binary here (gltf.check_glb), and read by the page's GLTFLoader."""

import math
import os

from .gltf import GlbError, check_glb
from .maps import grid_to_world

KEYS = {"name", "model", "easting", "northing", "heading_deg", "height"}
# A position this far from the products' origin is in another zone or a typo, not in the pit.
MAX_DISTANCE_M = 20000.0


class EquipmentError(Exception):
    """The equipment file's problems, one per line."""


def _number(item, key, where, problems, required=True):
    v = item.get(key)
    if v is None:
        if required:
            problems.append(f"{where}: {key} is missing")
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        problems.append(f"{where}: {key} must be a number, not {v!r}")
        return None
    return float(v)


def read_equipment(path):
    """The file's items: [{"name", "glb" (bytes), "easting", "northing", "heading_deg",
    "height" (None = on the surface)}]. Raises EquipmentError with every problem."""
    try:
        import yaml  # python3-yaml
    except ImportError:
        raise EquipmentError("reading an equipment file needs python3-yaml "
                             "(tools/install-deps.sh)")
    try:
        with open(path) as f:
            doc = yaml.safe_load(f)
    except OSError as e:
        raise EquipmentError(f"{path}: cannot read it: {e.strerror}")
    except yaml.YAMLError as e:
        raise EquipmentError(f"{path}: not YAML: {e}")
    if not isinstance(doc, dict) or not isinstance(doc.get("equipment"), list):
        raise EquipmentError(f"{path}: expected a map with a list 'equipment'")
    base = os.path.dirname(os.path.abspath(path))
    problems, items = [], []
    for k, item in enumerate(doc["equipment"]):
        where = f"{path}: equipment[{k}]"
        if not isinstance(item, dict):
            problems.append(f"{where}: expected a map")
            continue
        for key in sorted(set(item) - KEYS):
            problems.append(f"{where}: unknown key '{key}' (keys: {', '.join(sorted(KEYS))})")
        name = item.get("name")
        if not isinstance(name, str) or not name.strip():
            problems.append(f"{where}: name is missing")
        e, n = _number(item, "easting", where, problems), _number(item, "northing", where, problems)
        heading = _number(item, "heading_deg", where, problems, required=False) or 0.0
        height = _number(item, "height", where, problems, required=False)
        glb = None
        model = item.get("model")
        if not isinstance(model, str) or not model:
            problems.append(f"{where}: model is missing (a .glb file)")
        else:
            full = model if os.path.isabs(model) else os.path.join(base, model)
            try:
                with open(full, "rb") as f:
                    glb = f.read()
            except OSError as err:
                problems.append(f"{where}: model {model}: {err.strerror}")
            else:
                try:
                    check_glb(glb)
                except GlbError as err:
                    problems.append(f"{where}: model {model}: {err}")
        items.append({"name": name, "glb": glb, "easting": e, "northing": n,
                      "heading_deg": heading, "height": height})
    if problems:
        raise EquipmentError("\n".join(problems))
    return items


def place_equipment(items, summary):
    """World (ENU) positions of the items from the products' summary.json: the origin, the UTM
    zone and the vertical datum; a height in the datum becomes an ellipsoidal height by the
    datum's mean height. Raises EquipmentError for what cannot be placed."""
    o = summary.get("world_origin") or {}
    origin = tuple(o.get(k) for k in ("latitude_deg", "longitude_deg", "height_m"))
    grid = (summary.get("stages") or {}).get("grid") or {}
    epsg = grid.get("utm_epsg") or (summary.get("utm") or {}).get("epsg")
    if None in origin or not epsg:
        raise EquipmentError("equipment: the products have no world origin or UTM zone "
                             "(summary.json world_origin, stages.grid.utm_epsg): run the grid "
                             "stage first")
    vd = summary.get("vertical_datum") or {}
    datum_h = 0.0
    if vd.get("datum", "ellipsoid") != "ellipsoid" and vd.get("mean_datum_height_m") is not None:
        datum_h = float(vd["mean_datum_height_m"])
    problems, placed = [], []
    for item in items:
        h = item["height"] if item["height"] is not None else 0.0
        x, y, z = grid_to_world(origin, epsg, item["easting"], item["northing"], h + datum_h)
        x, y, z = float(x[0]), float(y[0]), float(z[0])
        if math.hypot(x, y) > MAX_DISTANCE_M:
            problems.append(f"equipment '{item['name']}': E {item['easting']:.1f}, N "
                            f"{item['northing']:.1f} is {math.hypot(x, y) / 1000:.1f} km from the "
                            f"survey (EPSG:{epsg}): another zone or a typo?")
            continue
        placed.append({"name": item["name"], "glb": item["glb"], "heading_deg": item["heading_deg"],
                       "position_m": [x, y, z if item["height"] is not None else None]})
    if problems:
        raise EquipmentError("\n".join(problems))
    return placed
