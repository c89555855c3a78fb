# SPDX-License-Identifier: MIT
"""Maps in the projected CRS of the products: GeoTIFF rasters (dem.tif, s44_holidays.tif,
mosaic.tif) read through GDAL with their geotransform, local world points (East, North, Up at
summary.json's world_origin) taken to the same grid, and the map furniture a chart needs:
easting/northing ticks, a scale bar, a north arrow (grid north) and the grid convergence."""

import math

import numpy as np
from matplotlib.patches import Rectangle
from matplotlib.ticker import FuncFormatter

# WGS 84 (the ellipsoid of pitmap's geodetic positions)
WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563


class MapError(Exception):
    """A raster or transform that cannot be drawn as a north-up map."""


def read_geotiff(path):
    """A GeoTIFF through GDAL (python3-gdal): {"bands": {description: float array (rows from
    the north)}, "gt": geotransform, "nx", "ny", "crs": horizontal CRS name, "epsg": its code or
    None, "metadata": the dataset metadata}. Raises MapError for a rotated raster, ImportError
    without python3-gdal."""
    from osgeo import gdal, osr  # python3-gdal: only the maps need it
    gdal.UseExceptions()
    ds = gdal.Open(path)
    gt = ds.GetGeoTransform()
    if gt[2] != 0 or gt[4] != 0 or gt[1] <= 0 or gt[5] >= 0:
        raise MapError(f"not a north-up raster (geotransform {gt})")
    bands = {}
    for b in range(1, ds.RasterCount + 1):
        band = ds.GetRasterBand(b)
        v = band.ReadAsArray().astype(np.float64)
        nodata = band.GetNoDataValue()
        if nodata is not None and not math.isnan(nodata):
            v[v == nodata] = np.nan
        bands[band.GetDescription() or f"band {b}"] = v
    crs, epsg = "", None
    wkt = ds.GetProjection()
    if wkt:
        srs = osr.SpatialReference()
        srs.ImportFromWkt(wkt)
        horizontal = srs.GetAttrValue("PROJCS") or srs.GetAttrValue("GEOGCS") or ""
        crs = horizontal
        code = srs.GetAuthorityCode("PROJCS")
        epsg = int(code) if code and code.isdigit() else None
    return {"bands": bands, "gt": gt, "nx": ds.RasterXSize, "ny": ds.RasterYSize, "crs": crs,
            "epsg": epsg, "metadata": ds.GetMetadata() or {}}


def raster_extent(gt, nx, ny):
    """(left, right, bottom, top) in CRS units of a north-up raster: its pixel edges."""
    return (gt[0], gt[0] + gt[1] * nx, gt[3] + gt[5] * ny, gt[3])


def nice_length(span, fraction=0.25):
    """The largest 1, 2 or 5 x 10^k not longer than fraction x span (a scale bar's length)."""
    if not span > 0:
        raise ValueError("span must be positive")
    target = fraction * span
    k = math.floor(math.log10(target))
    best = 10.0 ** k
    for m in (2.0, 5.0, 10.0):
        if m * 10.0 ** k <= target * (1 + 1e-12):
            best = m * 10.0 ** k
    return best


def add_scale_bar(ax, extent, units="m"):
    """A scale bar in the lower left of a map whose data units are metres of the grid: four
    black and white segments with the length under it, on a white box. Returns (x_start,
    x_end, length) in data units (x_end - x_start == length)."""
    left, right, bottom, top = extent
    width, height = right - left, top - bottom
    length = nice_length(width)
    x0 = left + 0.04 * width
    y0 = bottom + 0.05 * height
    bar_h = 0.012 * max(width, height)
    ax.add_patch(Rectangle((x0 - 0.015 * width, y0 - 0.6 * bar_h - 0.045 * height),
                           length + 0.03 * width, 0.045 * height + 2.2 * bar_h,
                           facecolor="white", edgecolor="0.4", lw=0.6, alpha=0.85, zorder=9))
    # 5 -> five segments of 1, 1 and 2 -> four of 0.25 and 0.5 (times 10^k).
    parts = 5 if round(length / 10.0 ** math.floor(math.log10(length))) == 5 else 4
    seg = length / parts
    for i in range(parts):
        ax.add_patch(Rectangle((x0 + i * seg, y0), seg, bar_h,
                               facecolor="black" if i % 2 == 0 else "white",
                               edgecolor="black", lw=0.8, zorder=10))
    label = f"{length:g} {units}"
    ax.text(x0 + length / 2, y0 - 0.5 * bar_h, label, ha="center", va="top", fontsize=9,
            zorder=10)
    ax.text(x0, y0 + 1.3 * bar_h, "0", ha="center", va="bottom", fontsize=7, zorder=10)
    ax.text(x0 + length, y0 + 1.3 * bar_h, f"{length:g}", ha="center", va="bottom", fontsize=7,
            zorder=10)
    return x0, x0 + length, length


def add_north_arrow(ax, label="grid north"):
    """An arrow pointing up the map (the grid's north: the rasters are north-up in the
    projected CRS), top right, with N and what north it is."""
    ax.annotate("", xy=(0.95, 0.95), xytext=(0.95, 0.83), xycoords="axes fraction",
                arrowprops={"arrowstyle": "-|>,head_width=0.5,head_length=0.9", "lw": 2,
                            "color": "black"}, zorder=10)
    ax.text(0.95, 0.955, "N", transform=ax.transAxes, ha="center", va="bottom", fontsize=13,
            weight="bold", zorder=10)
    ax.text(0.95, 0.815, label, transform=ax.transAxes, ha="center", va="top", fontsize=7,
            zorder=10, bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.7, "pad": 1})


def grid_axes(ax, crs_name):
    """Easting/northing tick labels in whole metres (no offset, thin-space grouping), the
    axis names with the CRS, a light grid."""
    fmt = FuncFormatter(lambda v, _: f"{v:,.0f}".replace(",", "\u2009"))
    ax.xaxis.set_major_formatter(fmt)
    ax.yaxis.set_major_formatter(fmt)
    ax.set_xlabel(f"Easting (m), {crs_name}" if crs_name else "Easting (m)")
    ax.set_ylabel("Northing (m)")
    ax.tick_params(labelsize=8)
    for t in ax.get_yticklabels():
        t.set_rotation(90)
        t.set_va("center")
    ax.grid(color="0.3", alpha=0.25, lw=0.5)
    ax.set_aspect("equal")


def add_furniture(ax, extent, crs_name, north="grid north"):
    """Grid ticks, scale bar and north arrow on a map; returns the scale bar's (start, end,
    length)."""
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    grid_axes(ax, crs_name)
    add_north_arrow(ax, north)
    return add_scale_bar(ax, extent)


def utm_central_meridian_deg(zone):
    return -183.0 + 6.0 * zone


def grid_convergence_deg(lat_deg, lon_deg, central_meridian_deg):
    """Angle from true north to grid north of a transverse Mercator grid at a point
    (first order: gamma = atan(tan(lon - lon0) sin(lat)), good to well under 0.01 deg within a
    UTM zone); positive east of the central meridian, where grid north lies east of true north."""
    dl = math.radians(lon_deg - central_meridian_deg)
    return math.degrees(math.atan(math.tan(dl) * math.sin(math.radians(lat_deg))))


def enu_to_ecef(origin, e, n, u):
    """Local East, North, Up metres at a geodetic origin (lat, lon, h; WGS 84) -> ECEF metres
    (the tangent plane at the origin, as pitmap's world frame)."""
    lat, lon, h = math.radians(origin[0]), math.radians(origin[1]), origin[2]
    e2 = WGS84_F * (2 - WGS84_F)
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    nu = WGS84_A_M / math.sqrt(1 - e2 * sl * sl)
    x0 = (nu + h) * cl * co
    y0 = (nu + h) * cl * so
    z0 = (nu * (1 - e2) + h) * sl
    e, n, u = (np.asarray(a, dtype=np.float64) for a in (e, n, u))
    x = x0 - so * e - sl * co * n + cl * co * u
    y = y0 + co * e - sl * so * n + cl * so * u
    z = z0 + cl * n + sl * u
    return x, y, z


def world_to_grid(origin, epsg, x, y, z=None):
    """World points (East, North, Up at the origin) -> (easting, northing) in EPSG `epsg`,
    through ECEF with GDAL's osr. Raises ImportError without python3-gdal."""
    from osgeo import osr
    x = np.asarray(x, dtype=np.float64)
    z = np.zeros_like(x) if z is None else np.asarray(z, dtype=np.float64)
    X, Y, Z = enu_to_ecef(origin, x, y, z)
    src, dst = osr.SpatialReference(), osr.SpatialReference()
    src.ImportFromEPSG(4978)
    dst.ImportFromEPSG(int(epsg))
    for s in (src, dst):
        s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    tr = osr.CoordinateTransformation(src, dst)
    pts = np.array(tr.TransformPoints(np.stack([X, Y, Z], axis=1).tolist()))
    if pts.size == 0:
        return np.zeros(0), np.zeros(0)
    return pts[:, 0], pts[:, 1]


def ecef_to_enu(origin, x, y, z):
    """ECEF metres -> local East, North, Up at a geodetic origin (the inverse of enu_to_ecef)."""
    lat, lon = math.radians(origin[0]), math.radians(origin[1])
    x0, y0, z0 = enu_to_ecef(origin, 0.0, 0.0, 0.0)
    dx, dy, dz = (np.asarray(a, dtype=np.float64) - b for a, b in ((x, x0), (y, y0), (z, z0)))
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    e = -so * dx + co * dy
    n = -sl * co * dx - sl * so * dy + cl * dz
    u = cl * co * dx + cl * so * dy + sl * dz
    return e, n, u


def geodetic_to_ecef(lat_deg, lon_deg, h):
    """WGS 84 latitude, longitude (degrees) and ellipsoidal height -> ECEF metres."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    e2 = WGS84_F * (2 - WGS84_F)
    nu = WGS84_A_M / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    return ((nu + h) * np.cos(lat) * np.cos(lon), (nu + h) * np.cos(lat) * np.sin(lon),
            (nu * (1 - e2) + h) * np.sin(lat))


def grid_to_world(origin, epsg, easting, northing, height):
    """(easting, northing) in EPSG `epsg` and ellipsoidal heights -> world points (East, North,
    Up at the origin): the inverse of world_to_grid. Raises ImportError without python3-gdal."""
    from osgeo import osr
    src, dst = osr.SpatialReference(), osr.SpatialReference()
    src.ImportFromEPSG(int(epsg))
    dst.ImportFromEPSG(4326)
    for s in (src, dst):
        s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    tr = osr.CoordinateTransformation(src, dst)
    e = np.atleast_1d(np.asarray(easting, dtype=np.float64))
    n = np.atleast_1d(np.asarray(northing, dtype=np.float64))
    pts = np.array(tr.TransformPoints(np.stack([e, n], axis=1).tolist()))
    x, y, z = geodetic_to_ecef(pts[:, 1], pts[:, 0], np.asarray(height, dtype=np.float64))
    return ecef_to_enu(origin, x, y, z)
