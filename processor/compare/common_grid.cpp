// SPDX-License-Identifier: MIT
#include "processor/compare/common_grid.hpp"

#include <cmath>
#include <cstdio>

namespace pitmap::proc::compare {

const char* ToString(Regridded r) {
    switch (r) {
        case Regridded::kA:
            return "a";
        case Regridded::kB:
            return "b";
        case Regridded::kNone:
            break;
    }
    return "none";
}

CommonGridPlan PlanCommonGrid(double resolution_a_m, double resolution_b_m) {
    CommonGridPlan plan;
    plan.resolution_m = std::min(resolution_a_m, resolution_b_m);
    if (std::abs(resolution_a_m - resolution_b_m) <= 1e-9) return plan;
    plan.regrid = resolution_a_m > resolution_b_m ? Regridded::kA : Regridded::kB;
    return plan;
}

Expected<CommonSurfaces> OnCommonGrid(SurfaceGrid a,
                                      SurfaceGrid b,
                                      const RegridSurvey& regrid_a,
                                      const RegridSurvey& regrid_b) {
    CommonSurfaces out;
    out.plan = PlanCommonGrid(a.resolution_m, b.resolution_m);
    if (out.plan.regrid != Regridded::kNone) {
        const bool is_a = out.plan.regrid == Regridded::kA;
        const RegridSurvey& regrid = is_a ? regrid_a : regrid_b;
        const char* who = is_a ? "A" : "B";
        if (!regrid) return Error{std::string("compare: no way to grid ") + who + " again"};
        auto again = regrid(out.plan.resolution_m);
        if (!again) return again.error();
        if (std::abs(again->resolution_m - out.plan.resolution_m) > 1e-9) {
            char buf[200];
            std::snprintf(buf,
                          sizeof buf,
                          "compare: %s gridded again came back at %.3f m, not the %.3f m asked",
                          who,
                          again->resolution_m,
                          out.plan.resolution_m);
            return Error{buf};
        }
        if (again->CountFilled() == 0)
            return Error{std::string("compare: ") + who + " gridded again holds no heights"};
        (is_a ? a : b) = std::move(*again);
    }
    out.a = std::move(a);
    out.b = std::move(b);
    return out;
}

}  // namespace pitmap::proc::compare
