// SPDX-License-Identifier: MIT
#include "processor/io/grid_io.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>

#include "common/formats/ply.hpp"
#include "common/formats/replace_file.hpp"

namespace pitmap::proc::io {

namespace {

constexpr double kBagNoData = 1000000.0;
// The heights' CRS when the grid names none (as io::LasWkt's vertical part): OGC 01-009
// vertical datum type 2002, ellipsoidal.
constexpr const char* kEllipsoidalWkt =
    "VERT_CS[\"WGS 84 ellipsoidal height\",VERT_DATUM[\"World Geodetic System 1984\",2002],"
    "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AXIS[\"Ellipsoidal height\",UP]]";

std::string VerticalWkt(const GridRaster& g) {
    return g.vertical_wkt.empty() ? std::string(kEllipsoidalWkt) : g.vertical_wkt;
}

// A VERT_CS of OGC 01-009 datum type 2002 (ellipsoidal): heights above the ellipsoid.
bool IsEllipsoidalVertical(const std::string& wkt) {
    const std::string key = "VERT_DATUM[\"";
    const auto a = wkt.find(key);
    if (a == std::string::npos) return false;
    const auto b = wkt.find('"', a + key.size());
    return b != std::string::npos && wkt.compare(b + 1, 5, ",2002") == 0;
}

void RegisterOnce() {
    static std::once_flag once;
    std::call_once(once, [] { GDALAllRegister(); });
}

// GDAL's errors go to its last-error slot instead of stderr while this lives.
class QuietErrors {
public:
    QuietErrors() {
        CPLPushErrorHandler(CPLQuietErrorHandler);
        CPLErrorReset();
    }
    ~QuietErrors() { CPLPopErrorHandler(); }
    QuietErrors(const QuietErrors&) = delete;
    QuietErrors& operator=(const QuietErrors&) = delete;
    static std::string Last() {
        const char* m = CPLGetLastErrorMsg();
        return m != nullptr && *m != 0 ? std::string(": ") + m : std::string();
    }
};

struct DatasetCloser {
    void operator()(GDALDataset* d) const {
        if (d != nullptr) GDALClose(d);
    }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

// "2026-05-14T09:12:03Z" -> the TIFF DateTime form "2026:05:14 09:12:03" ("" stays "").
std::string TiffDateTime(const std::string& iso) {
    if (iso.size() < 19) return "";
    std::string t = iso.substr(0, 19);
    t[4] = ':';
    t[7] = ':';
    t[10] = ' ';
    return t;
}

// The survey's metadata as TIFF tags (TIFF 6.0 section 8: DocumentName, ImageDescription,
// DateTime, Artist, Copyright, Software, which GDAL's GTiff driver writes from the items of the
// same names) and pitmap_* items (GDAL metadata, every field).
void SetTiffMetadata(GDALDataset& ds, const ProductMetadata& m, const std::string& layers) {
    const auto set = [&ds](const char* key, const std::string& value) {
        if (!value.empty()) ds.SetMetadataItem(key, value.c_str());
    };
    set("TIFFTAG_DOCUMENTNAME", m.Title());
    std::string description = layers;
    if (!m.Identification().empty()) description = m.Identification() + ": " + description;
    set("TIFFTAG_IMAGEDESCRIPTION", description);
    set("TIFFTAG_DATETIME", TiffDateTime(m.survey_end_utc));
    std::string artist = m.surveyor;
    if (!m.organisation.empty()) artist += (artist.empty() ? "" : ", ") + m.organisation;
    set("TIFFTAG_ARTIST", artist);
    if (!m.organisation.empty() || !m.client.empty()) {
        set("TIFFTAG_COPYRIGHT",
            m.client.empty() ? m.organisation
                             : (m.organisation.empty() ? "" : m.organisation + " for ") + m.client);
    }
    set("TIFFTAG_SOFTWARE", m.software);
    set("pitmap_project", m.project);
    set("pitmap_client", m.client);
    set("pitmap_site", m.site);
    set("pitmap_survey_id", m.survey_id);
    set("pitmap_surveyor", m.surveyor);
    set("pitmap_organisation", m.organisation);
    set("pitmap_vessel", m.vessel);
    set("pitmap_notes", m.notes);
    std::string equipment;
    for (const Equipment& e : m.equipment) {
        equipment += (equipment.empty() ? "" : "; ") + e.role + ": " + e.model;
    }
    set("pitmap_equipment", equipment);
    set("pitmap_survey_start_utc", m.survey_start_utc);
    set("pitmap_survey_end_utc", m.survey_end_utc);
    set("pitmap_processed_utc", m.processed_utc);
    set("pitmap_s44_order_target", m.s44_order_target);
    set("pitmap_horizontal_crs", m.horizontal_crs_name);
    set("pitmap_vertical_crs", m.vertical_crs_name);
}

// XML character data: & < > " escaped (GDAL pastes the BAG's VAR_ values into its template).
std::string XmlText(const std::string& s) {
    std::string o;
    for (const char c : s) {
        switch (c) {
            case '&':
                o += "&amp;";
                break;
            case '<':
                o += "&lt;";
                break;
            case '>':
                o += "&gt;";
                break;
            case '"':
                o += "&quot;";
                break;
            default:
                o += c;
        }
    }
    return o;
}

// The BAG's ISO 19115 metadata from the survey's (GDAL's bag_template.xml variables): the
// responsible party (surveyor, organisation), the citation (title, the survey's dates, the
// organisation), dateStamp = the survey's last day, the vertical uncertainty type
// ("productUncert": pitmap's uncertainty layer is a 95 % product uncertainty, not CUBE's 1-sigma
// standard deviation) and an abstract naming the project, client, vessel and equipment.
char** BagMetadataOptions(char** opts, const ProductMetadata& m) {
    // GDAL escapes these values itself (not the XML_ one, which is XML).
    const auto set = [&opts](const char* key, const std::string& value) {
        if (!value.empty()) opts = CSLSetNameValue(opts, key, value.c_str());
    };
    set("VAR_INDIVIDUAL_NAME", m.surveyor);
    set("VAR_ORGANISATION_NAME", m.organisation);
    set("VAR_POSITION_NAME", m.surveyor.empty() ? "" : "surveyor");
    set("VAR_DATE", m.SurveyEndDate());
    set("VAR_VERTICAL_UNCERT_CODE", "productUncert");
    // The date GDAL reports as BAG_DATETIME (the lineage's dateTime): the survey's end, so the
    // file is dated by its data; the processing time is in the process step's description.
    set("VAR_DATETIME", m.survey_end_utc);
    std::string abstract = "pitmap CUBE surface (multibeam survey)";
    if (!m.Identification().empty()) abstract += " of " + m.Identification();
    if (!m.client.empty()) abstract += " for " + m.client;
    if (!m.vessel.empty()) abstract += "; vessel " + m.vessel;
    for (const Equipment& e : m.equipment) abstract += "; " + e.role + " " + e.model;
    if (!m.survey_start_utc.empty()) {
        abstract += "; surveyed " + m.survey_start_utc + " to " + m.survey_end_utc;
    }
    if (!m.s44_order_target.empty()) abstract += "; IHO S-44 order targeted " + m.s44_order_target;
    abstract += "; vertical: " + m.vertical_crs_name;
    if (!m.notes.empty()) abstract += ". " + m.notes;
    set("VAR_ABSTRACT", abstract);
    // gmd:citation's content (the template wraps it in <gmd:citation>): CI_Citation with the
    // title, the survey's first day (CI_DateTypeCode "creation") and last day ("revision": the
    // ISO 19115:2003 codelist the BAG schema uses has no "completion"), the survey id and the
    // surveyor and organisation as originator.
    const auto date = [](const std::string& day, const char* type) {
        return "<gmd:date><gmd:CI_Date><gmd:date><gco:Date>" + day +
               "</gco:Date></gmd:date><gmd:dateType><gmd:CI_DateTypeCode "
               "codeList=\"http://www.isotc211.org/2005/resources/Codelist/"
               "gmxCodelists.xml#CI_DateTypeCode\" codeListValue=\"" +
               type + "\">" + type +
               "</gmd:CI_DateTypeCode></gmd:dateType></gmd:CI_Date></gmd:date>";
    };
    std::string citation = "<gmd:CI_Citation><gmd:title><gco:CharacterString>" +
                           XmlText(m.Identification().empty() ? m.Title() : m.Identification()) +
                           "</gco:CharacterString></gmd:title>";
    if (!m.survey_start_utc.empty()) citation += date(m.SurveyStartDate(), "creation");
    if (!m.survey_end_utc.empty()) citation += date(m.SurveyEndDate(), "revision");
    if (!m.survey_id.empty()) {
        citation += "<gmd:identifier><gmd:MD_Identifier><gmd:code><gco:CharacterString>" +
                    XmlText(m.survey_id) +
                    "</gco:CharacterString></gmd:code></gmd:MD_Identifier></gmd:identifier>";
    }
    if (!m.organisation.empty() || !m.surveyor.empty()) {
        citation += "<gmd:citedResponsibleParty><gmd:CI_ResponsibleParty>";
        if (!m.surveyor.empty()) {
            citation += "<gmd:individualName><gco:CharacterString>" + XmlText(m.surveyor) +
                        "</gco:CharacterString></gmd:individualName>";
        }
        if (!m.organisation.empty()) {
            citation += "<gmd:organisationName><gco:CharacterString>" + XmlText(m.organisation) +
                        "</gco:CharacterString></gmd:organisationName>";
        }
        citation +=
            "<gmd:role><gmd:CI_RoleCode codeList=\"http://www.isotc211.org/2005/resources/"
            "Codelist/gmxCodelists.xml#CI_RoleCode\" codeListValue=\"originator\">originator"
            "</gmd:CI_RoleCode></gmd:role></gmd:CI_ResponsibleParty></gmd:citedResponsibleParty>";
    }
    citation += "</gmd:CI_Citation>";
    opts = CSLSetNameValue(opts, "VAR_XML_IDENTIFICATION_CITATION", citation.c_str());
    return opts;
}

Status CheckGrid(const std::string& path, const GridRaster& g) {
    if (g.nx <= 0 || g.ny <= 0) return Error{path + ": empty grid"};
    if (!(g.resolution_m > 0) || !std::isfinite(g.x0) || !std::isfinite(g.y0)) {
        return Error{path + ": grid without a valid geometry"};
    }
    if (g.utm_zone < 1 || g.utm_zone > 60) {
        return Error{path + ": UTM zone " + std::to_string(g.utm_zone) + " is not 1..60"};
    }
    const std::size_t n = static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny);
    for (const GridLayer& l : g.layers) {
        if (l.values.size() != n) {
            return Error{path + ": layer " + l.name + " has " + std::to_string(l.values.size()) +
                         " values for " + std::to_string(n) + " nodes"};
        }
        const bool byte = g.sample_type == GridSampleType::kByte;
        if (!byte && (!l.class_names.empty() || !l.class_colours.empty())) {
            return Error{path + ": layer " + l.name +
                         ": class names or colours need a Byte raster"};
        }
        if (l.class_names.size() > kByteNoData || l.class_colours.size() > kByteNoData) {
            return Error{path + ": layer " + l.name + ": more than 255 classes"};
        }
        if (!byte) continue;
        for (const float v : l.values) {
            if (std::isfinite(v) && (v < 0 || v >= kByteNoData || v != std::floor(v))) {
                return Error{path + ": layer " + l.name + ": value " + std::to_string(v) +
                             " is not a whole number 0..254 (a Byte band)"};
            }
        }
    }
    return Ok{};
}

// The overview factors the COG driver would choose: halve until both sides are at most the
// tile size.
std::vector<int> OverviewFactors(int nx, int ny, int tile) {
    std::vector<int> f;
    for (int k = 1; nx > tile || ny > tile;) {
        k *= 2;
        f.push_back(k);
        nx = (nx + 1) / 2;
        ny = (ny + 1) / 2;
    }
    return f;
}

// GDAL's resampling of a band kind's overviews.
const char* OverviewResampling(GridBandKind k) {
    switch (k) {
        case GridBandKind::kContinuous:
            return "AVERAGE";
        case GridBandKind::kCount:
            return "NEAREST";
        case GridBandKind::kClass:
            return "MODE";
    }
    return "NEAREST";
}

// Overviews of every band of `ds` at `factors`, each band by its layer's kind. The MEM driver
// builds overviews of all bands at once (nearest), then each non-nearest band's are redone.
Status BuildBandOverviews(const std::string& path,
                          GDALDataset* ds,
                          const std::vector<const GridLayer*>& layers,
                          const std::vector<int>& factors) {
    if (factors.empty()) return Ok{};
    const int n = static_cast<int>(factors.size());
    if (GDALBuildOverviews(ds, "NEAREST", n, factors.data(), 0, nullptr, nullptr, nullptr) !=
        CE_None) {
        return Error{path + ": cannot build the overviews" + QuietErrors::Last()};
    }
    for (std::size_t b = 0; b < layers.size(); ++b) {
        const char* how = OverviewResampling(layers[b]->kind);
        if (std::strcmp(how, "NEAREST") == 0) continue;
        GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(b) + 1);
        std::vector<GDALRasterBandH> ovr;
        for (int k = 0; k < band->GetOverviewCount(); ++k) ovr.push_back(band->GetOverview(k));
        if (ovr.size() != factors.size() ||
            GDALRegenerateOverviews(
                band, static_cast<int>(ovr.size()), ovr.data(), how, nullptr, nullptr) != CE_None) {
            return Error{path + ": cannot build the overviews of " + layers[b]->name +
                         QuietErrors::Last()};
        }
    }
    return Ok{};
}

// Category names, colour table and the classes as band metadata of a kClass band.
void SetClasses(GDALRasterBand* band, const GridLayer& l) {
    if (!l.class_names.empty()) {
        CPLStringList names;
        std::string listed;
        for (std::size_t v = 0; v < l.class_names.size(); ++v) {
            names.AddString(l.class_names[v].c_str());
            listed += (v > 0 ? ", " : "") + std::to_string(v) + " " + l.class_names[v];
        }
        band->SetCategoryNames(names.List());
        band->SetMetadataItem("pitmap_classes", listed.c_str());
    }
    if (!l.class_colours.empty()) {
        GDALColorTable table(GPI_RGB);
        for (int v = 0; v <= kByteNoData; ++v) {
            std::array<std::uint8_t, 4> c{0, 0, 0, 0};  // unused values and no data: clear
            if (static_cast<std::size_t>(v) < l.class_colours.size()) c = l.class_colours[v];
            const GDALColorEntry e{c[0], c[1], c[2], c[3]};
            table.SetColorEntry(v, &e);
        }
        band->SetColorTable(&table);
        band->SetColorInterpretation(GCI_PaletteIndex);
    }
}

// An in-memory dataset of the given layers, north-up, with the compound CRS; `nodata` replaces
// NaN when finite.
Expected<DatasetPtr> MemDataset(const std::string& path,
                                const GridRaster& g,
                                const std::vector<const GridLayer*>& layers,
                                double nodata,
                                bool with_vertical) {
    GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
    if (mem == nullptr) return Error{path + ": GDAL has no MEM driver"};
    const bool byte = g.sample_type == GridSampleType::kByte;
    DatasetPtr ds(mem->Create(
        "", g.nx, g.ny, static_cast<int>(layers.size()), byte ? GDT_Byte : GDT_Float32, nullptr));
    if (!ds) return Error{path + ": cannot create the in-memory raster" + QuietErrors::Last()};
    const double r = g.resolution_m;
    double gt[6] = {g.x0 - r / 2, r, 0, g.y0 + (g.ny - 1) * r + r / 2, 0, -r};
    ds->SetGeoTransform(gt);
    // PROJ reads an ellipsoidal VERT_CS inside a COMPD_CS as horizontal only (ISO 19111 allows
    // no such compound), so the compound is assembled from its parts.
    OGRSpatialReference horizontal, vertical, srs;
    if (horizontal.importFromEPSG(static_cast<int>((g.northern ? 32600 : 32700) + g.utm_zone)) !=
            OGRERR_NONE ||
        vertical.importFromWkt(VerticalWkt(g).c_str()) != OGRERR_NONE ||
        srs.SetCompoundCS((horizontal.GetName() + std::string(" + ") + vertical.GetName()).c_str(),
                          &horizontal,
                          &vertical) != OGRERR_NONE) {
        return Error{path + ": cannot build the CRS" + QuietErrors::Last()};
    }
    OGRSpatialReference& used = with_vertical ? srs : horizontal;
    used.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    ds->SetSpatialRef(&used);
    if (with_vertical) {
        // GeoTIFF's keys hold a vertical CRS by EPSG code or by name only (no user datum, and
        // GDAL 3.6 cannot write UTM promoted to 3D into them: it falls back to a .aux.xml):
        // the whole CRS as WKT2 beside them, in the ISO 19111 form (ellipsoidal heights: the
        // UTM CRS promoted to 3D, as PROJ reads LAS's COMPD_CS).
        OGRSpatialReference iso(horizontal);
        const bool ellipsoidal = IsEllipsoidalVertical(VerticalWkt(g));
        if (ellipsoidal && iso.PromoteTo3D(nullptr) != OGRERR_NONE) {
            return Error{path + ": cannot build the 3D CRS" + QuietErrors::Last()};
        }
        const char* wkt2[] = {"FORMAT=WKT2_2019", "MULTILINE=NO", nullptr};
        char* text = nullptr;
        if ((ellipsoidal ? iso : srs).exportToWkt(&text, wkt2) == OGRERR_NONE && text != nullptr) {
            ds->SetMetadataItem("pitmap_crs_wkt", text);
        }
        CPLFree(text);
    }
    std::vector<float> row(static_cast<std::size_t>(g.nx));
    std::vector<std::uint8_t> row8(static_cast<std::size_t>(g.nx));
    for (std::size_t b = 0; b < layers.size(); ++b) {
        GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(b) + 1);
        band->SetDescription(layers[b]->name.c_str());
        if (!layers[b]->unit.empty()) band->SetUnitType(layers[b]->unit.c_str());
        for (const auto& [k, v] : layers[b]->metadata) band->SetMetadataItem(k.c_str(), v.c_str());
        if (byte) {
            band->SetNoDataValue(kByteNoData);
            SetClasses(band, *layers[b]);
        } else {
            band->SetNoDataValue(std::isfinite(nodata) ? nodata
                                                       : std::numeric_limits<double>::quiet_NaN());
        }
        for (int y = 0; y < g.ny; ++y) {
            const int j = g.ny - 1 - y;  // file row 0 is the north
            const float* src = layers[b]->values.data() + static_cast<std::size_t>(j) * g.nx;
            CPLErr e = CE_None;
            if (byte) {
                for (int i = 0; i < g.nx; ++i) {
                    row8[static_cast<std::size_t>(i)] =
                        std::isfinite(src[i]) ? static_cast<std::uint8_t>(src[i]) : kByteNoData;
                }
                e = band->RasterIO(GF_Write, 0, y, g.nx, 1, row8.data(), g.nx, 1, GDT_Byte, 0, 0);
            } else {
                for (int i = 0; i < g.nx; ++i) {
                    row[static_cast<std::size_t>(i)] =
                        std::isfinite(src[i]) || !std::isfinite(nodata)
                            ? src[i]
                            : static_cast<float>(nodata);
                }
                e = band->RasterIO(GF_Write, 0, y, g.nx, 1, row.data(), g.nx, 1, GDT_Float32, 0, 0);
            }
            if (e != CE_None) return Error{path + ": cannot fill the raster" + QuietErrors::Last()};
        }
    }
    for (const auto& [k, v] : g.metadata) ds->SetMetadataItem(k.c_str(), v.c_str());
    return ds;
}

Status Copy(const std::string& path, const char* driver_name, GDALDataset* src, char** options) {
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName(driver_name);
    if (drv == nullptr) return Error{path + ": GDAL has no " + driver_name + " driver"};
    DatasetPtr out(drv->CreateCopy(path.c_str(), src, FALSE, options, nullptr, nullptr));
    if (!out) return Error{path + ": cannot write (" + driver_name + ")" + QuietErrors::Last()};
    out.reset();  // flushes and closes
    if (CPLGetLastErrorType() >= CE_Failure) {
        return Error{path + ": error while writing" + QuietErrors::Last()};
    }
    return Ok{};
}

Status WriteCogGeoTiffTo(const std::string& path, const GridRaster& grid) {
    if (auto s = CheckGrid(path, grid); !s) return s;
    if (grid.layers.empty()) return Error{path + ": no layers"};
    RegisterOnce();
    QuietErrors quiet;
    std::vector<const GridLayer*> layers;
    for (const GridLayer& l : grid.layers) layers.push_back(&l);
    auto mem = MemDataset(
        path, grid, layers, std::numeric_limits<double>::quiet_NaN(), !grid.horizontal_only);
    if (!mem) return mem.error();
    if (grid.product) {
        std::string layer_names;
        for (const GridLayer& l : grid.layers) {
            layer_names += (layer_names.empty() ? "" : ", ") + l.name;
        }
        SetTiffMetadata(**mem, *grid.product, layer_names);
        // A raster of values that are not heights (the mosaic) has no vertical CRS.
        if (grid.horizontal_only) (*mem)->SetMetadataItem("pitmap_vertical_crs", nullptr);
    }
    constexpr int kTile = 256;
    if (auto o =
            BuildBandOverviews(path, mem->get(), layers, OverviewFactors(grid.nx, grid.ny, kTile));
        !o) {
        return o;
    }
    char** opts = nullptr;
    opts = CSLSetNameValue(opts, "COMPRESS", "DEFLATE");
    opts = CSLSetNameValue(opts, "PREDICTOR", "YES");
    opts = CSLSetNameValue(opts, "BLOCKSIZE", std::to_string(kTile).c_str());
    opts = CSLSetNameValue(opts, "NUM_THREADS", "2");
    // The overviews built above, per band (the driver's own would resample every band alike).
    opts = CSLSetNameValue(opts, "OVERVIEWS", "FORCE_USE_EXISTING");
    Status s = Copy(path, "COG", mem->get(), opts);
    CSLDestroy(opts);
    return s;
}

Status WriteBagTo(const std::string& path, const GridRaster& grid) {
    if (auto s = CheckGrid(path, grid); !s) return s;
    const GridLayer* elevation = nullptr;
    const GridLayer* uncertainty = nullptr;
    for (const GridLayer& l : grid.layers) {
        if (l.name == "elevation") elevation = &l;
        if (l.name == "uncertainty") uncertainty = &l;
    }
    if (elevation == nullptr || uncertainty == nullptr) {
        return Error{path + ": a BAG needs the layers elevation and uncertainty"};
    }
    if (grid.sample_type != GridSampleType::kFloat32) return Error{path + ": a BAG is Float32"};
    RegisterOnce();
    QuietErrors quiet;
    // The BAG's XML holds the horizontal and the vertical CRS apart (VAR_VERT_WKT).
    auto mem = MemDataset(path, grid, {elevation, uncertainty}, kBagNoData, /*vertical=*/false);
    if (!mem) return mem.error();
    char** opts = nullptr;
    const std::string vertical_wkt = VerticalWkt(grid);
    opts = CSLSetNameValue(opts, "VAR_VERT_WKT", vertical_wkt.c_str());
    opts = CSLSetNameValue(opts, "VAR_ABSTRACT", "pitmap CUBE surface (multibeam survey)");
    if (grid.product) opts = BagMetadataOptions(opts, *grid.product);
    std::string step =
        "pitmap: total propagated uncertainty per sounding (Hare et al. 1995), CUBE (Calder & "
        "Mayer 2003); vertical datum in the vertical CRS";
    if (grid.product && !grid.product->processed_utc.empty()) {
        step += "; processed " + grid.product->processed_utc + " with " + grid.product->software;
    }
    opts = CSLSetNameValue(opts, "VAR_PROCESS_STEP_DESCRIPTION", step.c_str());
    Status s = Copy(path, "BAG", mem->get(), opts);
    CSLDestroy(opts);
    return s;
}

}  // namespace

// Each product is written under a temporary name and renamed (common/formats/replace_file.hpp).
// GDAL's side file of what a GeoTIFF cannot hold (category names): PATH.aux.xml.
Status WriteCogGeoTiff(const std::string& path, const GridRaster& grid) {
    const std::string aux = path + ".aux.xml";
    const std::string partial_aux = formats::PartialPath(path) + ".aux.xml";
    std::remove(partial_aux.c_str());  // a killed writer's
    Status s = formats::WriteReplacing(
        path, [&](const std::string& partial) { return WriteCogGeoTiffTo(partial, grid); });
    std::FILE* f = std::fopen(partial_aux.c_str(), "rb");
    if (f == nullptr) {
        std::remove(aux.c_str());  // an earlier file's, which would describe this one
        return s;
    }
    std::fclose(f);
    if (!s) {
        std::remove(partial_aux.c_str());
        return s;
    }
    return formats::CommitPartial(partial_aux, aux);
}

Status WriteBag(const std::string& path, const GridRaster& grid) {
    return formats::WriteReplacing(
        path, [&](const std::string& partial) { return WriteBagTo(partial, grid); });
}

namespace {

CrsIdentity DescribeCrs(const OGRSpatialReference& srs) {
    CrsIdentity id;
    // WKT1 node names, searched through the tree (a compound CRS nests both).
    if (const char* h = srs.GetAttrValue("PROJCS"); h != nullptr) id.horizontal_name = h;
    if (const char* v = srs.GetAttrValue("VERT_CS"); v != nullptr) {
        id.vertical_name = v;
        if (const char* code = srs.GetAuthorityCode("VERT_CS"); code != nullptr) {
            id.vertical_epsg = std::atoi(code);
        }
        if (const char* datum = srs.GetAttrValue("VERT_DATUM"); datum != nullptr) {
            id.vertical_datum = datum;
        }
    } else if (srs.IsProjected() && srs.GetAxesCount() == 3) {
        // UTM promoted to 3D: the third axis is the ellipsoidal height of its datum.
        std::unique_ptr<OGRSpatialReference> base(srs.CloneGeogCS());
        const char* name = base != nullptr ? base->GetName() : nullptr;
        id.vertical_name = std::string(name != nullptr ? name : "?") + " ellipsoidal height";
        if (const char* datum = base != nullptr ? base->GetAttrValue("DATUM") : nullptr;
            datum != nullptr) {
            id.vertical_datum = datum;
        }
    }
    OGRSpatialReference horiz(srs);
    if (horiz.IsCompound()) horiz.StripVertical();
    if (horiz.GetAxesCount() == 3) horiz.DemoteTo2D(nullptr);
    horiz.AutoIdentifyEPSG();
    if (const char* code = horiz.GetAuthorityCode(nullptr); code != nullptr) {
        id.horizontal_epsg = std::atoi(code);
    }
    return id;
}

}  // namespace

Expected<CrsIdentity> DescribeCrsWkt(const std::string& wkt) {
    OGRSpatialReference srs;
    if (srs.importFromWkt(wkt.c_str()) != OGRERR_NONE) {
        return Error{"not a CRS that PROJ reads: " + wkt.substr(0, 80)};
    }
    return DescribeCrs(srs);
}

Expected<GridReadBack> ReadGrid(const std::string& path, std::size_t max_cells) {
    RegisterOnce();
    QuietErrors quiet;
    DatasetPtr ds(static_cast<GDALDataset*>(
        GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr)));
    if (!ds) return Error{path + ": cannot open as a raster" + QuietErrors::Last()};
    GridReadBack out;
    out.driver = ds->GetDriver() != nullptr ? ds->GetDriver()->GetDescription() : "";
    GridRaster& g = out.grid;
    g.nx = ds->GetRasterXSize();
    g.ny = ds->GetRasterYSize();
    if (g.nx <= 0 || g.ny <= 0) return Error{path + ": empty raster"};
    if (static_cast<double>(g.nx) * g.ny * std::max(1, ds->GetRasterCount()) >
        static_cast<double>(max_cells)) {
        return Error{path + ": raster larger than " + std::to_string(max_cells) + " cells"};
    }
    double gt[6];
    if (ds->GetGeoTransform(gt) != CE_None) return Error{path + ": no geotransform"};
    if (gt[2] != 0 || gt[4] != 0 || !(gt[1] > 0) || !(gt[5] < 0) ||
        std::abs(gt[1] + gt[5]) > 1e-9 * gt[1]) {
        return Error{path + ": not a north-up raster with square cells"};
    }
    g.resolution_m = gt[1];
    g.x0 = gt[0] + gt[1] / 2;
    g.y0 = gt[3] + gt[5] * (g.ny - 1) + gt[5] / 2;
    if (const OGRSpatialReference* srs = ds->GetSpatialRef(); srs != nullptr) {
        char* wkt = nullptr;
        if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt != nullptr) out.crs_wkt = wkt;
        CPLFree(wkt);
        const CrsIdentity id = DescribeCrs(*srs);
        out.horizontal_name = id.horizontal_name;
        out.horizontal_epsg = id.horizontal_epsg;
        out.vertical_name = id.vertical_name;
        out.vertical_epsg = id.vertical_epsg;
    }
    if (char** items = ds->GetMetadata(); items != nullptr) {
        for (char** p = items; *p != nullptr; ++p) {
            char* key = nullptr;
            const char* value = CPLParseNameValue(*p, &key);
            if (key != nullptr && value != nullptr) g.metadata.emplace_back(key, value);
            CPLFree(key);
        }
    }
    if (char** xml = ds->GetMetadata("xml:BAG"); xml != nullptr && xml[0] != nullptr) {
        out.bag_xml = xml[0];
    }
    const std::size_t n = static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny);
    std::vector<float> row(static_cast<std::size_t>(g.nx));
    for (int b = 1; b <= ds->GetRasterCount(); ++b) {
        GDALRasterBand* band = ds->GetRasterBand(b);
        GridLayer l;
        l.name = band->GetDescription();
        l.unit = band->GetUnitType() != nullptr ? band->GetUnitType() : "";
        if (b == 1 && band->GetRasterDataType() == GDT_Byte) g.sample_type = GridSampleType::kByte;
        if (char** names = band->GetCategoryNames(); names != nullptr) {
            for (int k = 0; names[k] != nullptr; ++k) l.class_names.emplace_back(names[k]);
        }
        int has_nodata = 0;
        const double nodata = band->GetNoDataValue(&has_nodata);
        l.values.resize(n);
        for (int y = 0; y < g.ny; ++y) {
            if (band->RasterIO(GF_Read, 0, y, g.nx, 1, row.data(), g.nx, 1, GDT_Float32, 0, 0) !=
                CE_None) {
                return Error{path + ": cannot read band " + std::to_string(b) +
                             QuietErrors::Last()};
            }
            float* dst = l.values.data() + static_cast<std::size_t>(g.ny - 1 - y) * g.nx;
            for (int i = 0; i < g.nx; ++i) {
                const float v = row[static_cast<std::size_t>(i)];
                dst[i] = has_nodata && std::isfinite(nodata) && v == static_cast<float>(nodata)
                             ? std::numeric_limits<float>::quiet_NaN()
                             : v;
            }
        }
        g.layers.push_back(std::move(l));
    }
    return out;
}

namespace {

Status WriteSoundingTpuPlyTo(const std::string& path,
                             const georef::GeorefResult& geo,
                             const std::vector<float>& thu_95_m,
                             const std::vector<float>& tvu_95_m,
                             const std::string& run_id) {
    const std::size_t n = geo.points.size();
    if (thu_95_m.size() != n || tvu_95_m.size() != n) {
        return Error{path + ": uncertainties for " + std::to_string(thu_95_m.size()) +
                     " soundings, " + std::to_string(n) + " soundings"};
    }
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr) return Error{formats::ErrnoMessage(path, "cannot create", errno)};
    char head[640];
    const std::string run_comment =
        run_id.empty() ? std::string() : "comment " + formats::ply::RunIdComment(run_id) + "\n";
    const Geodetic& o = geo.world_origin;
    std::snprintf(head,
                  sizeof head,
                  "ply\nformat binary_little_endian 1.0\ncomment pitmap_origin %.10f %.10f %.4f\n%s"
                  "comment pitmap per-sounding TPU, 95 %%: THU (horizontal), TVU (vertical)\n"
                  "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
                  "property double gps_time_s\nproperty float angle_deg\n"
                  "property float thu_95_m\nproperty float tvu_95_m\nend_header\n",
                  o.latitude_deg,
                  o.longitude_deg,
                  o.height_m,
                  run_comment.c_str(),
                  n);
    bool ok = std::fputs(head, f) >= 0;
    // 28-byte records, little-endian (the host order on every platform pitmap builds for is
    // checked below).
    static_assert(sizeof(float) == 4 && sizeof(double) == 8);
    const std::uint16_t probe = 1;
    unsigned char first = 0;
    std::memcpy(&first, &probe, 1);
    if (first != 1) {
        std::fclose(f);
        return Error{path + ": big-endian hosts are not supported"};
    }
    std::vector<unsigned char> buf;
    buf.reserve(28 * 65536);
    const auto put = [&buf](const void* p, std::size_t k) {
        const auto* b = static_cast<const unsigned char*>(p);
        buf.insert(buf.end(), b, b + k);
    };
    for (std::size_t j = 0; j < n && ok; ++j) {
        const Eigen::Vector3d& p = geo.points.position_world[j];
        const float xyz[3] = {
            static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
        const double t = static_cast<double>(geo.pings[geo.points.ping[j]].utime_gps) * 1e-6;
        const float rest[3] = {
            static_cast<float>(geo.points.angle_rad[j] * 180.0 / M_PI), thu_95_m[j], tvu_95_m[j]};
        put(xyz, sizeof xyz);
        put(&t, sizeof t);
        put(rest, sizeof rest);
        if (buf.size() >= 28 * 65536 || j + 1 == n) {
            ok = std::fwrite(buf.data(), 1, buf.size(), f) == buf.size();
            buf.clear();
        }
    }
    ok = ok && std::fflush(f) == 0;
    const int err = errno;
    ok = (std::fclose(f) == 0) && ok;
    if (!ok) return Error{formats::ErrnoMessage(path, "write failed", err)};
    return Ok{};
}

}  // namespace

Status WriteSoundingTpuPly(const std::string& path,
                           const georef::GeorefResult& geo,
                           const std::vector<float>& thu_95_m,
                           const std::vector<float>& tvu_95_m,
                           const std::string& run_id) {
    return formats::WriteReplacing(path, [&](const std::string& partial) {
        return WriteSoundingTpuPlyTo(partial, geo, thu_95_m, tvu_95_m, run_id);
    });
}

Status WriteVrt(const std::string& vrt_path, const std::vector<std::string>& tiles) {
    if (tiles.empty()) return Error{vrt_path + ": no tiles"};
    RegisterOnce();
    QuietErrors quiet;
    // The tiles are opened by their paths beside the VRT; GDAL writes each source relative to
    // the VRT when its path is (relativeToVRT="1").
    const std::string slash = vrt_path.find('/') == std::string::npos
                                  ? std::string()
                                  : vrt_path.substr(0, vrt_path.rfind('/') + 1);
    std::vector<std::string> paths;
    for (const std::string& t : tiles) paths.push_back(slash + t);
    std::vector<const char*> names;
    for (const std::string& p : paths) names.push_back(p.c_str());
    char** argv = nullptr;
    argv = CSLAddString(argv, "-srcnodata");
    argv = CSLAddString(argv, "nan");
    argv = CSLAddString(argv, "-vrtnodata");
    argv = CSLAddString(argv, "nan");
    GDALBuildVRTOptions* options = GDALBuildVRTOptionsNew(argv, nullptr);
    CSLDestroy(argv);
    if (options == nullptr) return Error{vrt_path + ": GDALBuildVRT options" + QuietErrors::Last()};
    int usage_error = 0;
    GDALDatasetH vrt = GDALBuildVRT(vrt_path.c_str(),
                                    static_cast<int>(names.size()),
                                    nullptr,
                                    names.data(),
                                    options,
                                    &usage_error);
    GDALBuildVRTOptionsFree(options);
    if (vrt == nullptr || usage_error != 0) {
        if (vrt != nullptr) GDALClose(vrt);
        return Error{vrt_path + ": cannot build the VRT" + QuietErrors::Last()};
    }
    CPLErrorReset();
    GDALClose(vrt);
    if (CPLGetLastErrorType() >= CE_Failure) {
        return Error{vrt_path + ": cannot write the VRT" + QuietErrors::Last()};
    }
    return Ok{};
}

}  // namespace pitmap::proc::io
