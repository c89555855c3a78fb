# SPDX-License-Identifier: MIT
"""glTF 2.0 binary (.glb) files for the viewer: the container check (Khronos glTF 2.0
specification, section "GLB File Format Specification": a 12-byte header, magic "glTF",
version 2, the total length; then a JSON chunk and an optional BIN chunk, each with an 8-byte
header: length and type) and the self-contained HTML page that shows one file in the
report's 3D viewer (`pitmap-report --view-gltf FILE.glb`)."""

import base64
import json
import os
import struct

from .sections_viewer import missing_viewer_files, viewer_html
from .util import esc, num

GLB_MAGIC = 0x46546C67  # "glTF", little-endian
CHUNK_JSON = 0x4E4F534A  # "JSON"
CHUNK_BIN = 0x004E4942  # "BIN\0"
# The page carries the file as base64 inside a JSON string; browsers give up on strings of
# about 512 M characters, so larger files are refused (report.html's "open glTF..." reads a
# local file of any size directly).
MAX_GLB_BYTES = 300_000_000


class GlbError(Exception):
    """Bytes that are not a glTF 2.0 binary this viewer can show."""


def check_glb(data):
    """Checks a .glb's bytes: header (magic, version 2, length = the size of the data), the JSON
    chunk (in bounds, a JSON object with asset.version 2.x), the BIN chunk when present (in
    bounds) and that nothing refers to a file outside it. Returns the parsed JSON; raises
    GlbError with what is wrong."""
    n = len(data)
    if n < 12:
        raise GlbError(f"too short for a glTF binary ({n} bytes; the header alone is 12)")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != GLB_MAGIC:
        raise GlbError(f'not a glTF binary: it starts with {bytes(data[:4])!r}, not "glTF"')
    if version != 2:
        raise GlbError(f"glTF binary version {version}; only version 2 is read")
    if length > n:
        raise GlbError(f"truncated: its header says {length} bytes, the file has {n}")
    if length < n:
        raise GlbError(f"its header says {length} bytes, but the file has {n} (bytes after "
                       "the end)")
    if n < 20:
        raise GlbError("no JSON chunk after the header")
    json_len, json_type = struct.unpack_from("<II", data, 12)
    if json_type != CHUNK_JSON:
        raise GlbError(f"the first chunk is of type 0x{json_type:08x}, not JSON")
    if 20 + json_len > n:
        raise GlbError(f"truncated: the JSON chunk says {json_len} bytes, the file has "
                       f"{n - 20} after its header")
    try:
        doc = json.loads(bytes(data[20:20 + json_len]).decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as e:
        raise GlbError(f"the JSON chunk is not JSON: {e}")
    if not isinstance(doc, dict):
        raise GlbError("the JSON chunk is not a JSON object")
    asset = doc.get("asset")
    if not isinstance(asset, dict) or not str(asset.get("version", "")).startswith("2"):
        raise GlbError("the JSON chunk has no asset.version 2.x")
    at = 20 + json_len
    at += (4 - at % 4) % 4
    if at + 8 <= n:
        bin_len, bin_type = struct.unpack_from("<II", data, at)
        if bin_type == CHUNK_BIN and at + 8 + bin_len > n:
            raise GlbError(f"truncated: the BIN chunk says {bin_len} bytes, the file has "
                           f"{n - at - 8} after its header")
    for kind in ("buffers", "images"):
        items = doc.get(kind) or []
        if not isinstance(items, list):
            raise GlbError(f"{kind} is not a list")
        for item in items:
            uri = item.get("uri") if isinstance(item, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                raise GlbError(f"it refers to a file outside it ({kind}: {uri!r}); only "
                               "self-contained .glb files are shown")
    return doc


def triangles(doc):
    """Triangles of the file's triangle-list primitives, from the accessor counts."""
    accessors = doc.get("accessors") or []
    total = 0
    for mesh in doc.get("meshes") or []:
        for prim in mesh.get("primitives") or []:
            if prim.get("mode", 4) != 4:
                continue
            a = prim.get("indices")
            if a is None:
                a = (prim.get("attributes") or {}).get("POSITION")
            if isinstance(a, int) and 0 <= a < len(accessors):
                total += int(accessors[a].get("count", 0)) // 3
    return total


def gltf_page(path, title=None):
    """The self-contained HTML page of one .glb: the report's viewer with the file embedded
    (base64). Raises GlbError for a file that is not a glTF binary, OSError when it cannot be
    read, FileNotFoundError naming the viewer's missing JavaScript files."""
    size = os.path.getsize(path)
    if size > MAX_GLB_BYTES:
        raise GlbError(f"{num(size)} bytes; this page embeds at most {num(MAX_GLB_BYTES)} "
                       "(open larger files with report.html's \"open glTF...\")")
    with open(path, "rb") as f:
        data = f.read()
    doc = check_glb(data)
    absent = missing_viewer_files()
    if absent:
        raise FileNotFoundError("not found: " + ", ".join(absent) +
                                " (Debian's libjs-three: tools/install-deps.sh)")
    from .report import CSS, PAGE  # matplotlib only when a page is really written

    name = os.path.basename(path)
    facts = [f"{num(size)} bytes", f"{num(triangles(doc))} triangles"]
    origin = ((doc.get("asset") or {}).get("extras") or {}).get("pitmap_origin")
    if isinstance(origin, dict):
        facts.append("pitmap origin {:.7f}, {:.7f}, {:.2f} m".format(
            float(origin.get("latitude_deg", 0)), float(origin.get("longitude_deg", 0)),
            float(origin.get("height_m", 0))))
    caption = (f"{esc(name)}: {esc(', '.join(facts))}. glTF is y-up; shown z-up in local ENU "
               "metres (pitmap's mesh.glb: East, Up, -North), coloured by its own vertex "
               "colours (else by depth). Drag to turn, wheel to zoom, right-drag to pan; "
               "cross-section, distance, enter VR (real size) and open glTF... as in the "
               "report.")
    data_json = {"gltf": {"name": name, "glb": base64.b64encode(data).decode("ascii")}}
    title = title or f"pitmap glTF view: {name}"
    return PAGE.format(title=esc(title), subtitle="glTF 2.0 binary in pitmap's 3D viewer", toc="",
                       notes="", body=viewer_html(data_json, caption), css=CSS,
                       footer="pitmap-report --view-gltf.")
