// SPDX-License-Identifier: MIT
// What every product says about its survey (issue 39): who, where, with what, when, and the
// coordinate reference systems of its coordinates. Filled once per stage by the pipeline
// (processor/pipeline/metadata.hpp: the config's `metadata:` section, the vehicle file's
// equipment, the survey's first and last ping) and written by each product's writer in the
// place its format has for it (docs/georeferencing.md lists them). Plain values, no I/O.
#pragma once

#include <string>
#include <vector>

namespace pitmap {

struct Equipment {
    std::string role;   // "multibeam" | "gnss_ins"
    std::string model;  // as vehicle.yaml names it
};

struct ProductMetadata {
    // The config's metadata section; "" = not set.
    std::string project, client, site, survey_id, surveyor, organisation, vessel, notes;
    std::string s44_order_target;  // "" = none named ("exclusive", "special", "1a", "1b", "2")
    std::vector<Equipment> equipment;
    // ISO 8601 UTC to the second with a Z ("2026-05-14T09:12:03Z"); "" = unknown.
    std::string survey_start_utc, survey_end_utc, processed_utc;
    std::string software;  // "pitmap 0.1.0"
    // The products' CRS: horizontal (WGS 84 / UTM zone) and vertical (the vertical datum).
    std::string horizontal_crs_name;
    int horizontal_epsg = 0;  // 0 = none
    std::string vertical_crs_name;
    int vertical_epsg = 0;  // 0 = none (ellipsoidal heights, a water level)
    std::string vertical_description;

    // A title for a product: the project, else the site, else "pitmap survey".
    std::string Title() const {
        if (!project.empty()) return project;
        if (!site.empty()) return site;
        return "pitmap survey";
    }
    // "project, site, survey id" joined by " / " (what is set of them).
    std::string Identification() const {
        std::string s;
        for (const std::string* p : {&project, &site, &survey_id}) {
            if (p->empty()) continue;
            if (!s.empty()) s += " / ";
            s += *p;
        }
        return s;
    }
    // The survey's first and last day, "YYYY-MM-DD" ("" when unknown).
    std::string SurveyStartDate() const { return survey_start_utc.substr(0, 10); }
    std::string SurveyEndDate() const { return survey_end_utc.substr(0, 10); }
};

}  // namespace pitmap
