// SPDX-License-Identifier: MIT
// The survey's metadata (issue 39): the config's `metadata:` section (who and where), the
// vehicle file's equipment and the survey's dates, as the products write them
// (common/product_metadata.hpp) and as summary.json's "metadata" object (docs/georeferencing.md
// has its schema).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/product_metadata.hpp"
#include "common/vehicle.hpp"

namespace pitmap::proc::hydro {
struct DatumModel;
}

namespace pitmap::proc::pipeline {

// The `metadata:` section: free text, every key optional ("" = not given).
struct SurveyMetadataConfig {
    std::string project;           // e.g. "Bejanca pit bathymetry 2026"
    std::string client;            // who the survey is for
    std::string site;              // the pit's name (names a water-level vertical datum)
    std::string survey_id;         // the organisation's reference
    std::string surveyor;          // the person responsible
    std::string organisation;      // the surveyor's organisation
    std::string vessel;            // the vehicle's name; "" = vehicle.yaml's name
    std::string s44_order_target;  // "" | exclusive | special | 1a | 1b | 2
    std::string notes;

    // Every problem: an S-44 order pitmap does not know, a control character or a value
    // longer than kMaxMetadataChars (the fields go into fixed header fields and XML).
    std::vector<std::string> Validate() const;
};
inline constexpr std::size_t kMaxMetadataChars = 500;

// What the products say: `config`'s text, the vessel (config, else vehicle name), the
// equipment the vehicle file names (sonar.model: multibeam, ins.model: gnss_ins), the survey's
// first and last ping (GPS microseconds; UTC through `gps_minus_utc_s`), `processed_unix_us`
// (the wall clock of the run, Unix microseconds), the horizontal CRS (UTM zone) and the datum.
struct MetadataInputs {
    const VehicleDescription* vehicle = nullptr;
    std::optional<std::int64_t> first_ping_utime_gps, last_ping_utime_gps;
    int gps_minus_utc_s = 18;
    std::int64_t processed_unix_us = 0;
    int utm_zone = 0;  // 0 = unknown
    bool northern = true;
    const hydro::DatumModel* datum = nullptr;  // nullptr = WGS 84 ellipsoidal heights
};
ProductMetadata BuildProductMetadata(const SurveyMetadataConfig& config, const MetadataInputs& in);

// summary.json's "metadata": every text field a string ("" unset), epsg codes int or null,
// s44_order_target string or null.
nlohmann::json MetadataJson(const ProductMetadata& m);

// "YYYY-MM-DDThh:mm:ssZ" of Unix microseconds.
std::string IsoUtcSeconds(std::int64_t utime_unix);
// "pitmap <version>".
std::string SoftwareName();

}  // namespace pitmap::proc::pipeline
