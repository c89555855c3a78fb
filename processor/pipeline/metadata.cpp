// SPDX-License-Identifier: MIT
#include "processor/pipeline/metadata.hpp"

#include <chrono>
#include <cstdio>

#include "common/geodesy.hpp"
#include "common/gps_time.hpp"
#include "common/product_metadata_json.hpp"
#include "common/version.hpp"
#include "processor/hydro/datum.hpp"
#include "processor/hydro/s44.hpp"
#include "processor/pipeline/internal.hpp"

namespace pitmap::proc::pipeline {

std::vector<std::string> SurveyMetadataConfig::Validate() const {
    std::vector<std::string> p;
    const std::pair<const char*, const std::string*> fields[] = {
        {"project", &project},
        {"client", &client},
        {"site", &site},
        {"survey_id", &survey_id},
        {"surveyor", &surveyor},
        {"organisation", &organisation},
        {"vessel", &vessel},
        {"s44_order_target", &s44_order_target},
        {"notes", &notes}};
    for (const auto& [key, value] : fields) {
        const std::string where = "metadata." + std::string(key);
        if (value->size() > kMaxMetadataChars) {
            p.push_back(where + " is " + std::to_string(value->size()) + " characters, more than " +
                        std::to_string(kMaxMetadataChars));
        }
        // Only the notes may have more lines: the others go into one-line header fields.
        const bool lines = value == &notes;
        for (const char c : *value) {
            if (static_cast<unsigned char>(c) < 0x20 && !(lines && c == '\n')) {
                p.push_back(where + (lines ? " holds a control character (only newlines)"
                                           : " must be one line without control characters"));
                break;
            }
        }
    }
    hydro::S44Order order{};
    if (!s44_order_target.empty() && !hydro::S44OrderFromString(s44_order_target, &order)) {
        p.push_back("metadata.s44_order_target \"" + s44_order_target +
                    "\" is not an IHO S-44 order pitmap knows (exclusive | special | 1a | 1b | 2)");
    }
    return p;
}

std::string IsoUtcSeconds(std::int64_t utime_unix) {
    const UtcCalendar c = UtcCalendarFromUnix(utime_unix);
    char b[32];
    std::snprintf(b,
                  sizeof b,
                  "%04d-%02d-%02dT%02d:%02d:%02dZ",
                  c.year,
                  c.month,
                  c.day,
                  c.hour,
                  c.minute,
                  c.second);
    return b;
}

std::string SoftwareName() {
    return std::string("pitmap ") + Version();
}

ProductMetadata BuildProductMetadata(const SurveyMetadataConfig& c, const MetadataInputs& in) {
    ProductMetadata m;
    m.project = c.project;
    m.client = c.client;
    m.site = c.site;
    m.survey_id = c.survey_id;
    m.surveyor = c.surveyor;
    m.organisation = c.organisation;
    m.vessel = c.vessel;
    m.notes = c.notes;
    m.s44_order_target = c.s44_order_target;
    if (in.vehicle != nullptr) {
        if (m.vessel.empty()) m.vessel = in.vehicle->name;
        if (!in.vehicle->sonar_model.empty()) {
            m.equipment.push_back({"multibeam", in.vehicle->sonar_model});
        }
        if (!in.vehicle->ins_model.empty()) {
            m.equipment.push_back({"gnss_ins", in.vehicle->ins_model});
        }
    }
    if (in.first_ping_utime_gps) {
        m.survey_start_utc =
            IsoUtcSeconds(UnixFromGps(*in.first_ping_utime_gps, in.gps_minus_utc_s));
    }
    if (in.last_ping_utime_gps) {
        m.survey_end_utc = IsoUtcSeconds(UnixFromGps(*in.last_ping_utime_gps, in.gps_minus_utc_s));
    }
    if (in.processed_unix_us > 0) m.processed_utc = IsoUtcSeconds(in.processed_unix_us);
    m.software = SoftwareName();
    if (in.utm_zone >= 1 && in.utm_zone <= 60) {
        m.horizontal_epsg = UtmEpsgCode(in.utm_zone, in.northern);
        m.horizontal_crs_name =
            "WGS 84 / UTM zone " + std::to_string(in.utm_zone) + (in.northern ? "N" : "S");
    }
    const hydro::DatumModel ellipsoid;
    const hydro::DatumModel& d = in.datum != nullptr ? *in.datum : ellipsoid;
    m.vertical_crs_name = d.crs_name;
    m.vertical_epsg = d.vertical_epsg;
    m.vertical_description = d.description.empty() ? "heights above the WGS 84 ellipsoid "
                                                     "(the ellipsoidal height of EPSG:4979)"
                                                   : d.description;
    return m;
}

nlohmann::json MetadataJson(const ProductMetadata& m) {
    return ProductMetadataJson(m);
}

}  // namespace pitmap::proc::pipeline

namespace pitmap::proc::pipeline::detail {

ProductMetadata SurveyProductMetadata(StageContext& s,
                                      const PipelineConfig& config,
                                      const hydro::DatumModel* datum) {
    std::optional<VehicleDescription> vehicle = s.vehicle;
    if (!vehicle && !s.model.vehicle_yaml.empty()) {
        // The metadata's equipment only: a vehicle file unreadable now was read by georef.
        if (auto v = ReadVehicleFile(s.model.vehicle_yaml); v) vehicle = std::move(*v);
    }
    MetadataInputs in;
    in.vehicle = vehicle ? &*vehicle : nullptr;
    const auto& pings = s.model.ingest.pings.pings;
    if (!pings.empty()) {
        in.first_ping_utime_gps = pings.front().utime_gps;
        in.last_ping_utime_gps = pings.back().utime_gps;
        const int leap = s.model.ingest.nav.leap_seconds;
        in.gps_minus_utc_s = leap >= 0 ? leap : LeapSecondsAtGps(pings.front().utime_gps);
    }
    in.processed_unix_us = std::chrono::duration_cast<std::chrono::microseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
    if (auto u = UtmFromGeodetic(s.model.origin); u && u->zone >= 1) {
        in.utm_zone = u->zone;
        in.northern = u->northern;
    }
    in.datum = datum;
    ProductMetadata m = BuildProductMetadata(config.metadata, in);
    if (pings.empty()) {
        // The pings freed (`run` before the mesh) or not loaded: the span georef recorded
        // (summary.json "time", microseconds cut to the second).
        const auto t = s.summary.find("time");
        const auto cut = [](const nlohmann::json& v) {
            return v.is_string() && v.get<std::string>().size() >= 19
                       ? v.get<std::string>().substr(0, 19) + "Z"
                       : std::string();
        };
        if (t != s.summary.end() && t->is_object()) {
            m.survey_start_utc = cut(t->value("first_ping_utc", nlohmann::json()));
            m.survey_end_utc = cut(t->value("last_ping_utc", nlohmann::json()));
        }
    }
    s.summary["metadata"] = MetadataJson(m);
    return m;
}

}  // namespace pitmap::proc::pipeline::detail
