# SPDX-License-Identifier: MIT
"""Whether two products folders of `pitmap run` hold the same products, apart from what
differs between any two runs of the same command: the run id (a random 128-bit id stamped
into every product), the processing time, the time and memory figures of summary.json, and
the ids and clocks that the container formats stamp themselves (the LAS file GUID and creation
date, the OpenVDB file UUID, the HDF5 object times of the BAG). Everything else is compared
byte for byte, the BAG's grids and metadata through GDAL.

    differences(a, b) -> list of strings (empty: the same products)
"""
import json
import os
import re
import struct

# summary.json keys that measure the run rather than describe the products.
TIMING_KEY = re.compile(r"(^|_)seconds($|_)|^timings|rss|^(cpu|merge|prepare|rasterise)_s$")
PROCESSED_UTC = re.compile(rb'(processed_utc"?\s*[>:]\s*"?)\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?Z')
UUID = re.compile(rb"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")


def run_id(folder):
    with open(os.path.join(folder, "summary.json")) as f:
        return json.load(f)["run_id"]


def _strip_timings(v):
    if isinstance(v, dict):
        return {k: _strip_timings(x) for k, x in v.items()
                if not TIMING_KEY.search(k) and k not in ("run_id", "processed_utc")}
    if isinstance(v, list):
        return [_strip_timings(x) for x in v]
    return v


def _masked(data, rid):
    data = data.replace(rid.encode(), b"R" * 32)
    return PROCESSED_UTC.sub(lambda m: m.group(1) + b"T" * (len(m.group(0)) - len(m.group(1))), data)


def _survey_sections(data, rid):
    """survey.pitmap's sections {tag: payload} (processor/survey/survey_file.hpp), the state
    section's run id masked; the CRCs are left out (they follow from the payloads)."""
    if data[:8] != b"PMSURVEY":
        return None
    _, _, n = struct.unpack_from("<III", data, 8)
    pos, out = 20, {}
    for _ in range(n):
        tag = data[pos:pos + 16].rstrip(b"\0").decode()
        (size,) = struct.unpack_from("<Q", data, pos + 16)
        payload = data[pos + 28:pos + 28 + size]
        out[tag] = payload.replace(rid.encode(), b"R" * 32)
        pos += 28 + size
    return out


def _bag(path):
    from osgeo import gdal
    gdal.UseExceptions()
    ds = gdal.Open(path)
    bands = [ds.GetRasterBand(i + 1).ReadAsArray().tobytes() for i in range(ds.RasterCount)]
    meta = {dom or "": ds.GetMetadata(dom or "") for dom in (ds.GetMetadataDomainList() or [])}
    text = json.dumps(meta, sort_keys=True).replace(path, "FILE").encode()
    # The ISO 19115 record's dateStamp: the processing date (seconds differ between runs).
    text = re.sub(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?Z?", b"T", text)
    return ds.GetGeoTransform(), ds.RasterXSize, ds.RasterYSize, bands, text


def _same_file(name, pa, pb, ra, rb):
    if name == "summary.json":
        with open(pa) as fa, open(pb) as fb:
            return _strip_timings(json.load(fa)) == _strip_timings(json.load(fb))
    with open(pa, "rb") as fa, open(pb, "rb") as fb:
        da, db = fa.read(), fb.read()
    if name.endswith(".bag"):
        return _bag(pa) == _bag(pb)
    if name == "survey.pitmap":
        return _survey_sections(da, ra) == _survey_sections(db, rb)
    da, db = _masked(da, ra), _masked(db, rb)
    if name.endswith(".las") and len(da) >= 94 and len(db) >= 94:
        # Header: project GUID (bytes 8-23, from the run id) and creation day and year (90-93).
        def mask(d):
            return d[:8] + b"\0" * 16 + d[24:90] + b"\0" * 4 + d[94:]
        da, db = mask(da), mask(db)
    if name.endswith(".vdb"):
        # OpenVDB's file UUID, and the CRC-32 of pitmap's 24-byte trailer that covers it
        # (processor/fusion/vdb_io.hpp: "PMVDBCRC", u64 length, u32 CRC, u32 version).
        def mask(d):
            d = UUID.sub(b"U" * 36, d)
            if len(d) >= 24 and d[-24:-16] == b"PMVDBCRC":
                d = d[:-8] + b"\0" * 4 + d[-4:]
            return d
        da, db = mask(da), mask(db)
    return da == db


def differences(a, b):
    """What differs between products folders a and b (a list of strings, empty if nothing)."""
    ra, rb = run_id(a), run_id(b)
    fa = {n for n in os.listdir(a) if not n.startswith(".")}
    fb = {n for n in os.listdir(b) if not n.startswith(".")}
    out = [f"only in {a}: {n}" for n in sorted(fa - fb)]
    out += [f"only in {b}: {n}" for n in sorted(fb - fa)]
    for n in sorted(fa & fb):
        pa, pb = os.path.join(a, n), os.path.join(b, n)
        if os.path.isdir(pa) or os.path.isdir(pb):
            if not (os.path.isdir(pa) and os.path.isdir(pb)):
                out.append(f"{n}: a folder in one, a file in the other")
            else:
                out += [f"{n}/{d}" for d in differences_tree(pa, pb, ra, rb)]
            continue
        if not _same_file(n, pa, pb, ra, rb):
            out.append(f"{n} differs")
    return out


def differences_tree(a, b, ra, rb):
    fa, fb = set(os.listdir(a)), set(os.listdir(b))
    out = [f"only in one: {n}" for n in sorted(fa ^ fb)]
    for n in sorted(fa & fb):
        pa, pb = os.path.join(a, n), os.path.join(b, n)
        if os.path.isdir(pa):
            out += [f"{n}/{d}" for d in differences_tree(pa, pb, ra, rb)]
        elif not _same_file(n, pa, pb, ra, rb):
            out.append(f"{n} differs")
    return out
