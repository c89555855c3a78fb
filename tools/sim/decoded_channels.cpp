// SPDX-License-Identifier: MIT
#include "tools/sim/decoded_channels.hpp"

#include <cmath>
#include <limits>

#include "common/protocol/novatel/decoder.hpp"
#include "pitmap/multibeam_ping_t.hpp"

namespace pitmap::sim {
namespace nv = protocol::novatel;
namespace dt = protocol::deltat;

DecodedChannels::DecodedChannels(const ScenarioConfig& sc) {
    imu_.imu_rate_hz = sc.imu_rate_hz;
}

std::vector<acq::EncodedMessage> DecodedChannels::NovatelChunk(ByteSpan chunk, std::int64_t utime) {
    std::vector<acq::EncodedMessage> out;
    framer_.Push(chunk);
    while (true) {
        auto ev = framer_.Next();
        if (std::holds_alternative<protocol::NeedMore>(ev)) break;
        if (std::holds_alternative<protocol::Skipped>(ev)) {
            ++failures_;
            continue;
        }
        nv::DecodeResult r = nv::Decode(std::get<nv::Frame>(ev));
        if (!nv::IsMessage(r)) {
            ++failures_;
            continue;
        }
        if (const auto* cfg = std::get_if<nv::InsConfig>(&r))
            imu_.imu_type = static_cast<std::int32_t>(cfg->imu_type);
        if (auto msg =
                acq::EncodeNovatel(nv::ToMessage(std::move(r)), utime, "novatel_com1", imu_)) {
            out.push_back(std::move(*msg));
        }
    }
    return out;
}

std::vector<acq::EncodedMessage> DecodedChannels::SonarDatagram(ByteSpan datagram,
                                                                std::int64_t utime,
                                                                std::int64_t utime_gps) {
    std::vector<acq::EncodedMessage> out;
    auto r = dt::DecodeRecord83PInto(datagram, float_order_, ping_);
    if (!std::holds_alternative<dt::RecordKind>(r) ||
        std::get<dt::RecordKind>(r) != dt::RecordKind::kPing) {
        ++failures_;
        return out;
    }
    const auto msg = acq::ToLcm(ping_,
                                utime,
                                utime_gps,
                                pitmap::multibeam_ping_t::TIME_SOURCE_HEADER_CLOCK,
                                std::numeric_limits<float>::quiet_NaN());
    out.push_back(
        {acq::ChannelName(acq::kChannelMultibeamPing, "deltat_udp"), acq::EncodeLcm(msg)});
    return out;
}

}  // namespace pitmap::sim
