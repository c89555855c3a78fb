// SPDX-License-Identifier: MIT
// The decoded LCM channels of a simulated survey, produced through the same code path as the
// daemon: common/protocol framers and decoders, then firmware_host/daemon/to_lcm. Feeding it
// the raw chunks in arrival order yields exactly what pitmap-acqd publishes for them.
#pragma once

#include <cstdint>
#include <vector>

#include "common/byte_io.hpp"
#include "common/protocol/deltat/record83p.hpp"
#include "common/protocol/novatel/framer.hpp"
#include "firmware_host/daemon/to_lcm.hpp"
#include "tools/sim/scenario.hpp"

namespace pitmap::sim {

class DecodedChannels {
public:
    explicit DecodedChannels(const ScenarioConfig& scenario);
    // Decoded messages completed by this chunk of the NovAtel stream.
    std::vector<acq::EncodedMessage> NovatelChunk(ByteSpan chunk, std::int64_t utime_host);
    // The ping of one 83P datagram; the daemon's clock model is taken as exact (utime_gps of
    // the transmit, source HEADER_CLOCK).
    std::vector<acq::EncodedMessage> SonarDatagram(ByteSpan datagram,
                                                   std::int64_t utime_host,
                                                   std::int64_t utime_gps_transmit);
    // Frames or datagrams that did not decode (always 0 for the simulator's own bytes).
    std::int64_t failures() const { return failures_; }

private:
    protocol::novatel::Framer framer_;
    acq::ImuContext imu_;
    protocol::deltat::FloatOrderMemory float_order_;
    protocol::deltat::Ping83P ping_;
    std::int64_t failures_ = 0;
};

}  // namespace pitmap::sim
