// SPDX-License-Identifier: MIT
#include "processor/io/geoid.hpp"

#include <proj.h>

#include <cmath>
#include <cstdio>

namespace pitmap::proc::io {

struct GeoidGrid::Impl {
    PJ_CONTEXT* ctx = nullptr;
    PJ* pj = nullptr;
    ~Impl() {
        if (pj != nullptr) proj_destroy(pj);
        if (ctx != nullptr) proj_context_destroy(ctx);
    }
};

GeoidGrid::~GeoidGrid() = default;
GeoidGrid::GeoidGrid(GeoidGrid&&) noexcept = default;
GeoidGrid& GeoidGrid::operator=(GeoidGrid&&) noexcept = default;

Expected<GeoidGrid> GeoidGrid::Open(const std::string& grid) {
    if (grid.empty()) return Error{"geoid: no grid named"};
    for (char c : grid) {
        if (c == ' ' || c == '+' || c == '\n' || c == '\t' || c == '@' || c == ',') {
            return Error{"geoid grid '" + grid +
                         "': the name may not hold spaces, '+', '@' or ','"};
        }
    }
    GeoidGrid g;
    g.name_ = grid;
    g.impl_ = std::make_unique<Impl>();
    g.impl_->ctx = proj_context_create();
    if (g.impl_->ctx == nullptr) return Error{"geoid: cannot create a PROJ context"};
    proj_log_level(g.impl_->ctx, PJ_LOG_NONE);
    proj_context_set_enable_network(g.impl_->ctx, 0);
    // vgridshift's forward step adds multiplier * grid value to the height: with multiplier 1
    // and a zero height it returns N itself.
    const std::string def = "+proj=vgridshift +grids=" + grid + " +multiplier=1";
    g.impl_->pj = proj_create(g.impl_->ctx, def.c_str());
    if (g.impl_->pj == nullptr) {
        const int e = proj_context_errno(g.impl_->ctx);
        return Error{"geoid grid '" + grid + "' cannot be opened by PROJ (" +
                     proj_context_errno_string(g.impl_->ctx, e) +
                     "); install proj-data (egm96_15.gtx) or give a path to the grid"};
    }
    return g;
}

Expected<std::vector<double>> GeoidGrid::Undulations(const std::vector<Geodetic>& points) const {
    std::vector<double> out(points.size());
    for (std::size_t k = 0; k < points.size(); ++k) {
        const Geodetic& p = points[k];
        PJ_COORD c = proj_coord(
            p.longitude_deg * M_PI / 180.0, p.latitude_deg * M_PI / 180.0, 0.0, HUGE_VAL);
        proj_errno_reset(impl_->pj);
        const PJ_COORD r = proj_trans(impl_->pj, PJ_FWD, c);
        if (!std::isfinite(r.xyz.z) || std::abs(r.xyz.z) > 1000 || proj_errno(impl_->pj) != 0) {
            char b[160];
            std::snprintf(b,
                          sizeof b,
                          "geoid grid '%s' has no value at latitude %.6f, longitude %.6f",
                          name_.c_str(),
                          p.latitude_deg,
                          p.longitude_deg);
            return Error{b};
        }
        out[k] = r.xyz.z;
    }
    return out;
}

}  // namespace pitmap::proc::io
