// SPDX-License-Identifier: MIT
// A survey's scans integrated into a TSDF a batch at a time as they are made (from blocks of
// the georeferenced view), carrying across each batch's edges the neighbouring pings its
// integration reads, so that a stage never holds the survey's scans whole. docs/decisions/034.
#pragma once

#include <cstddef>
#include <vector>

#include "common/progress.hpp"
#include "processor/fusion/tsdf.hpp"

namespace pitmap::proc::fusion {

// The scans on each side of a scan that its integration reads (beam-width mode):
// NeighbourPings(config) (the gap to the neighbouring fans, the runs of missing beams bridged
// across ping_gap_bridge_pings, the along-track slope; decisions 026, 039), at least one.
// TsdfVolume::Integrate(scans, begin, end) is the whole survey's integration of [begin, end)
// when `scans` holds this many of the survey's scans on each side of it (fewer only at the
// survey's ends).
std::size_t NeighbourScans(const TsdfConfig& config);

// A survey's scans integrated as they are made, a batch at a time, without holding them all:
// each batch of `batch_scans` is integrated once the NeighbourScans after it have been added,
// and the scans no later batch reads as a neighbour are dropped. The volume is the one a single
// Integrate over all the scans gives, voxel for voxel (each call reads the neighbours the whole
// sequence would give it: TsdfVolume::Integrate(scans, begin, end)). Holds at most
// batch_scans + 2 NeighbourScans + the scans of one Add. docs/decisions/034.
class ScanStreamIntegrator {
public:
    // batch_scans (at least 1): scans per Integrate call. total_scans: the survey's scans, for
    // the progress fraction (0: unknown, no progress); progress returning false cancels (the
    // volume then holds a partial integration, and later scans are ignored).
    ScanStreamIntegrator(TsdfVolume& volume,
                         std::size_t batch_scans,
                         std::size_t total_scans = 0,
                         ProgressCallback progress = nullptr);

    // The survey's next scans, in order (moved in).
    void Add(std::vector<SonarScan>&& scans);
    // No more scans: integrates those left. The counts of every call summed (active_voxels:
    // the volume's), the message as one Integrate's.
    IntegrateResult Finish();

    std::size_t max_held() const { return max_held_; }  // the most scans held at once
    std::size_t calls() const { return calls_; }        // Integrate calls made

private:
    void IntegrateTo(std::size_t end);  // integrates [done_, end), survey indices

    TsdfVolume& volume_;
    std::size_t batch_;
    std::size_t total_;
    std::size_t reach_;
    ProgressCallback progress_;
    std::vector<SonarScan> held_;
    std::size_t first_ = 0;  // survey index of held_[0]
    std::size_t done_ = 0;   // survey index of the first scan not integrated
    std::size_t max_held_ = 0;
    std::size_t calls_ = 0;
    IntegrateResult sum_;
    bool integrated_ = false;  // some call had beams to integrate
};

}  // namespace pitmap::proc::fusion
