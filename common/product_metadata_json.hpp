// SPDX-License-Identifier: MIT
// ProductMetadata as JSON (header-only: its users link nlohmann_json themselves): summary.json's
// "metadata" object, the LAS metadata VLR and glTF's asset.extras.pitmap_metadata. Every text
// field is a string ("" = unset), EPSG codes an integer or null, s44_order_target a string or
// null (docs/georeferencing.md has the schema).
#pragma once

#include <nlohmann/json.hpp>

#include "common/product_metadata.hpp"

namespace pitmap {

inline nlohmann::json ProductMetadataJson(const ProductMetadata& m) {
    using nlohmann::json;
    json equipment = json::array();
    for (const Equipment& e : m.equipment) {
        equipment.push_back({{"role", e.role}, {"model", e.model}});
    }
    const auto code = [](int epsg) { return epsg > 0 ? json(epsg) : json(); };
    return {
        {"project", m.project},
        {"client", m.client},
        {"site", m.site},
        {"survey_id", m.survey_id},
        {"surveyor", m.surveyor},
        {"organisation", m.organisation},
        {"vessel", m.vessel},
        {"notes", m.notes},
        {"equipment", equipment},
        {"survey_start_utc", m.survey_start_utc},
        {"survey_end_utc", m.survey_end_utc},
        {"processed_utc", m.processed_utc},
        {"software", m.software},
        {"horizontal_crs", {{"name", m.horizontal_crs_name}, {"epsg", code(m.horizontal_epsg)}}},
        {"vertical_crs",
         {{"name", m.vertical_crs_name},
          {"epsg", code(m.vertical_epsg)},
          {"description", m.vertical_description}}},
        {"s44_order_target", m.s44_order_target.empty() ? json() : json(m.s44_order_target)}};
}

}  // namespace pitmap
