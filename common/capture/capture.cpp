// SPDX-License-Identifier: MIT
// Link, network and transport header layouts: IEEE 802.3 / 802.1Q, tcpdump.org LINKTYPE_LINUX_SLL
// and LINKTYPE_LINUX_SLL2 pages, RFC 791 (IPv4), RFC 8200 (IPv6), RFC 9293 (TCP), RFC 768 (UDP).
#include "common/capture/capture.hpp"

#include <arpa/inet.h>
#include <pcap/pcap.h>
#include <sys/stat.h>
#include <zlib.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <utility>

namespace pitmap::capture {
namespace {

constexpr std::uint16_t kEtherTypeIpv4 = 0x0800;
constexpr std::uint16_t kEtherTypeIpv6 = 0x86DD;
constexpr std::uint16_t kEtherTypeVlan = 0x8100;
constexpr std::uint16_t kEtherTypeQinQ = 0x88A8;
constexpr std::uint16_t kEtherTypeQinQOld = 0x9100;
constexpr std::uint8_t kIpProtoTcp = 6;
constexpr std::uint8_t kIpProtoUdp = 17;
constexpr int kLinkTypeIpv4 = 228;  // DLT_IPV4 (raw IPv4, no version sniffing)
constexpr int kLinkTypeIpv6 = 229;  // DLT_IPV6
constexpr int kLinkTypeSll2 = 276;  // DLT_LINUX_SLL2
constexpr int kLinkTypeLoop = 108;  // DLT_LOOP (network byte order family)

std::string ErrnoText(int err) {
    return std::strerror(err);
}

Expected<std::vector<std::uint8_t>> Gunzip(const std::vector<std::uint8_t>& in,
                                           const std::string& path) {
    std::vector<std::uint8_t> out;
    out.reserve(in.size() * 4);
    z_stream zs{};
    // 16 + MAX_WBITS: gzip wrapper only (RFC 1952).
    if (inflateInit2(&zs, 16 + MAX_WBITS) != Z_OK) {
        return Error{path + ": cannot initialise zlib"};
    }
    zs.next_in = const_cast<Bytef*>(in.data());
    zs.avail_in = static_cast<uInt>(in.size());
    std::uint8_t buf[1 << 16];
    int rc = Z_OK;
    while (true) {
        zs.next_out = buf;
        zs.avail_out = sizeof(buf);
        rc = inflate(&zs, Z_NO_FLUSH);
        out.insert(out.end(), buf, buf + (sizeof(buf) - zs.avail_out));
        if (rc == Z_STREAM_END) {
            // gzip files may hold several members back to back; anything else after the end
            // (zero padding from some tools) is ignored, as gzip(1) does.
            if (zs.avail_in >= 2 && zs.next_in[0] == 0x1F && zs.next_in[1] == 0x8B) {
                inflateReset(&zs);
                continue;
            }
            break;
        }
        if (rc == Z_BUF_ERROR && zs.avail_in == 0) {
            inflateEnd(&zs);
            return Error{path + ": truncated gzip data (" + std::to_string(out.size()) +
                         " bytes decompressed before the end)"};
        }
        if (rc != Z_OK && rc != Z_BUF_ERROR) {
            const std::string msg = zs.msg != nullptr ? zs.msg : "error " + std::to_string(rc);
            inflateEnd(&zs);
            return Error{path + ": corrupt gzip data: " + msg};
        }
    }
    inflateEnd(&zs);
    return out;
}

std::string FormatAddress(int family, const std::uint8_t* addr) {
    char text[INET6_ADDRSTRLEN] = {};
    if (inet_ntop(family, addr, text, sizeof(text)) == nullptr) return "?";
    return text;
}

// The network layer of one packet: where the IP header starts and which IP version it is.
struct NetworkLayer {
    int ip_version = 0;  // 4, 6, or 0 = not IP
    ByteSpan bytes;
};

std::optional<NetworkLayer> FromEtherType(std::uint16_t ether_type, ByteSpan rest) {
    if (ether_type == kEtherTypeIpv4) return NetworkLayer{4, rest};
    if (ether_type == kEtherTypeIpv6) return NetworkLayer{6, rest};
    return NetworkLayer{0, rest};
}

std::optional<NetworkLayer> FromVersionNibble(ByteSpan rest) {
    if (rest.empty()) return std::nullopt;
    const int version = rest[0] >> 4;
    return NetworkLayer{(version == 4 || version == 6) ? version : 0, rest};
}

// BSD loopback: a 4-byte address family, host order of the capturing machine (DLT_NULL) or
// network order (DLT_LOOP). AF_INET is 2 everywhere; AF_INET6 is 10, 24, 28 or 30 by OS.
std::optional<NetworkLayer> FromLoopback(ByteSpan packet, bool network_order) {
    if (packet.size() < 4) return std::nullopt;
    ByteReader r(packet);
    std::uint32_t family = network_order ? r.U32Be() : r.U32Le();
    if (!network_order && family > 0xFFFF) family = ByteReader(packet).U32Be();
    const ByteSpan rest = packet.subspan(4);
    if (family == 2) return NetworkLayer{4, rest};
    if (family == 10 || family == 24 || family == 28 || family == 30) return NetworkLayer{6, rest};
    return NetworkLayer{0, rest};
}

// nullopt = the link header itself is cut short.
std::optional<NetworkLayer> ParseLink(int link_type, ByteSpan packet) {
    switch (link_type) {
        case DLT_EN10MB: {
            if (packet.size() < 14) return std::nullopt;
            std::size_t off = 12;
            std::uint16_t type = ByteReader(packet.subspan(off)).U16Be();
            while (type == kEtherTypeVlan || type == kEtherTypeQinQ || type == kEtherTypeQinQOld) {
                off += 4;
                if (packet.size() < off + 2) return std::nullopt;
                type = ByteReader(packet.subspan(off)).U16Be();
            }
            return FromEtherType(type, packet.subspan(off + 2));
        }
        case DLT_LINUX_SLL:
            if (packet.size() < 16) return std::nullopt;
            return FromEtherType(ByteReader(packet.subspan(14)).U16Be(), packet.subspan(16));
        case kLinkTypeSll2:
            if (packet.size() < 20) return std::nullopt;
            return FromEtherType(ByteReader(packet).U16Be(), packet.subspan(20));
        case DLT_RAW:
            return FromVersionNibble(packet);
        case kLinkTypeIpv4:
            return NetworkLayer{4, packet};
        case kLinkTypeIpv6:
            return NetworkLayer{6, packet};
        case DLT_NULL:
            return FromLoopback(packet, false);
        case kLinkTypeLoop:
            return FromLoopback(packet, true);
        default:
            return NetworkLayer{0, packet};
    }
}

bool LinkTypeSupported(int link_type) {
    return link_type == DLT_EN10MB || link_type == DLT_LINUX_SLL || link_type == kLinkTypeSll2 ||
           link_type == DLT_RAW || link_type == kLinkTypeIpv4 || link_type == kLinkTypeIpv6 ||
           link_type == DLT_NULL || link_type == kLinkTypeLoop;
}

// The transport layer of one IP packet.
struct TransportLayer {
    std::uint8_t protocol = 0;
    Endpoint src;  // ports filled in later
    Endpoint dst;
    ByteSpan bytes;          // transport header + payload, trimmed to the IP length
    bool truncated = false;  // the IP packet is longer than what was captured
    bool fragment = false;
};

std::optional<TransportLayer> ParseIpv4(ByteSpan ip) {
    if (ip.size() < 20 || (ip[0] >> 4) != 4) return std::nullopt;
    const std::size_t header_len = static_cast<std::size_t>(ip[0] & 0x0F) * 4;
    ByteReader r(ip);
    r.Seek(2);
    const std::size_t total_len = r.U16Be();
    r.Seek(6);
    const std::uint16_t frag = r.U16Be();
    if (header_len < 20 || ip.size() < header_len || total_len < header_len) return std::nullopt;
    TransportLayer t;
    t.protocol = ip[9];
    t.src.address = FormatAddress(AF_INET, ip.data() + 12);
    t.dst.address = FormatAddress(AF_INET, ip.data() + 16);
    // More-fragments flag or a non-zero offset.
    t.fragment = (frag & 0x3FFF) != 0;
    // The IP length trims Ethernet padding; a shorter capture means the snap length cut it.
    const std::size_t end = std::min(total_len, ip.size());
    t.truncated = total_len > ip.size();
    t.bytes = ip.subspan(header_len, end - header_len);
    return t;
}

std::optional<TransportLayer> ParseIpv6(ByteSpan ip) {
    if (ip.size() < 40 || (ip[0] >> 4) != 6) return std::nullopt;
    ByteReader r(ip);
    r.Seek(4);
    const std::size_t payload_len = r.U16Be();
    TransportLayer t;
    t.src.address = FormatAddress(AF_INET6, ip.data() + 8);
    t.dst.address = FormatAddress(AF_INET6, ip.data() + 24);
    const std::size_t end = std::min(40 + payload_len, ip.size());
    t.truncated = 40 + payload_len > ip.size();
    std::uint8_t next = ip[6];
    std::size_t off = 40;
    // Skip extension headers (RFC 8200 §4): hop-by-hop, routing, destination options, AH.
    while (true) {
        if (next == 0 || next == 43 || next == 60 || next == 51) {
            if (end < off + 2) return std::nullopt;
            const std::size_t len = next == 51 ? (static_cast<std::size_t>(ip[off + 1]) + 2) * 4
                                               : (static_cast<std::size_t>(ip[off + 1]) + 1) * 8;
            next = ip[off];
            off += len;
            if (off > end) return std::nullopt;
            continue;
        }
        if (next == 44) {  // fragment header
            t.fragment = true;
            if (end < off + 8) return std::nullopt;
            next = ip[off];
            off += 8;
            continue;
        }
        break;
    }
    t.protocol = next;
    t.bytes = ip.subspan(off, end - off);
    return t;
}

struct PcapCloser {
    void operator()(pcap_t* p) const { pcap_close(p); }
};

class CaptureBuilder {
public:
    explicit CaptureBuilder(int link_type) : link_type_(link_type) {}

    void AddPacket(std::int64_t utime, ByteSpan packet, bool snapped, CaptureStats& stats) {
        ++stats.packets;
        if (stats.packets == 1) stats.first_utime = utime;
        stats.last_utime = utime;
        const auto link = ParseLink(link_type_, packet);
        if (!link) {
            ++stats.truncated_packets;
            return;
        }
        if (link->ip_version == 0) {
            ++stats.non_ip_packets;
            return;
        }
        auto ip = link->ip_version == 4 ? ParseIpv4(link->bytes) : ParseIpv6(link->bytes);
        if (!ip) {
            ++stats.truncated_packets;
            return;
        }
        if (ip->fragment) {
            ++stats.ip_fragments;
            return;
        }
        const bool truncated = ip->truncated || snapped;
        if (ip->protocol == kIpProtoTcp) {
            AddTcp(utime, *ip, truncated, stats);
        } else if (ip->protocol == kIpProtoUdp) {
            AddUdp(utime, *ip, truncated, stats);
        } else {
            ++stats.other_ip_packets;
        }
    }

    CaptureContents Finish(CaptureStats stats) {
        CaptureContents out;
        out.stats = std::move(stats);
        out.udp = std::move(udp_);
        out.tcp.reserve(flows_.size());
        for (auto& flow : flows_) {
            flow.reassembler.Finish();
            TcpStream s;
            s.src = std::move(flow.src);
            s.dst = std::move(flow.dst);
            s.bytes = std::move(flow.reassembler.mutable_bytes());
            s.chunks = flow.reassembler.chunks();
            s.gaps = flow.reassembler.stream_gaps();
            s.first_utime = flow.reassembler.first_utime();
            s.last_utime = flow.reassembler.last_utime();
            s.stats = flow.reassembler.stats();
            out.tcp.push_back(std::move(s));
        }
        return out;
    }

private:
    struct Flow {
        Endpoint src;
        Endpoint dst;
        TcpReassembler reassembler;
    };

    void AddTcp(std::int64_t utime, TransportLayer& ip, bool truncated, CaptureStats& stats) {
        const ByteSpan seg = ip.bytes;
        if (seg.size() < 20) {
            ++stats.truncated_packets;
            return;
        }
        const std::size_t header_len = static_cast<std::size_t>(seg[12] >> 4) * 4;
        if (header_len < 20 || seg.size() < header_len) {
            ++stats.truncated_packets;
            return;
        }
        ++stats.tcp_packets;
        if (truncated) ++stats.truncated_payloads;
        ByteReader r(seg);
        ip.src.port = r.U16Be();
        ip.dst.port = r.U16Be();
        const std::uint32_t seq = r.U32Be();
        const std::uint8_t flags = seg[13];
        const bool fin = (flags & 0x01) != 0;
        const bool syn = (flags & 0x02) != 0;
        const bool rst = (flags & 0x04) != 0;

        const std::string key = ip.src.ToString() + ">" + ip.dst.ToString();
        auto it = index_.find(key);
        // A new SYN on a 4-tuple whose connection was closed starts a new stream.
        if (it != index_.end() && syn) {
            const auto& old = flows_[it->second].reassembler.stats();
            if (old.fin_seen || old.rst_seen) it = index_.end();
        }
        if (it == index_.end()) {
            flows_.push_back(Flow{ip.src, ip.dst, TcpReassembler{}});
            it = index_.insert_or_assign(key, flows_.size() - 1).first;
        }
        flows_[it->second].reassembler.AddSegment(
            utime, seq, syn, fin, rst, seg.subspan(header_len));
    }

    void AddUdp(std::int64_t utime, TransportLayer& ip, bool truncated, CaptureStats& stats) {
        const ByteSpan dgram = ip.bytes;
        if (dgram.size() < 8) {
            ++stats.truncated_packets;
            return;
        }
        ++stats.udp_packets;
        ByteReader r(dgram);
        ip.src.port = r.U16Be();
        ip.dst.port = r.U16Be();
        const std::size_t len = r.U16Be();
        std::size_t payload_len = dgram.size() - 8;
        // A UDP length of 0 is legal over IPv6 jumbograms; otherwise it bounds the payload.
        if (len >= 8 && len - 8 < payload_len) payload_len = len - 8;
        if (truncated || (len >= 8 && len - 8 > payload_len)) ++stats.truncated_payloads;
        const ByteSpan payload = dgram.subspan(8, payload_len);
        udp_.push_back(UdpDatagram{utime, ip.src, ip.dst, {payload.begin(), payload.end()}});
    }

    int link_type_;
    std::vector<Flow> flows_;
    std::map<std::string, std::size_t> index_;
    std::vector<UdpDatagram> udp_;
};

}  // namespace

std::string Endpoint::ToString() const {
    if (address.find(':') != std::string::npos) {
        return "[" + address + "]:" + std::to_string(port);
    }
    return address + ":" + std::to_string(port);
}

Expected<std::vector<std::uint8_t>> ReadFileBytes(const std::string& path) {
    struct stat st {};
    if (stat(path.c_str(), &st) != 0) {
        return Error{path + ": " + ErrnoText(errno)};
    }
    if (S_ISDIR(st.st_mode)) return Error{path + ": is a directory"};
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
    if (!f) return Error{path + ": " + ErrnoText(errno)};
    std::vector<std::uint8_t> data;
    if (S_ISREG(st.st_mode)) data.reserve(static_cast<std::size_t>(st.st_size));
    std::uint8_t buf[1 << 16];
    while (true) {
        const std::size_t n = std::fread(buf, 1, sizeof(buf), f.get());
        data.insert(data.end(), buf, buf + n);
        if (n < sizeof(buf)) break;
    }
    if (std::ferror(f.get()) != 0) return Error{path + ": read error"};
    if (data.size() >= 2 && data[0] == 0x1F && data[1] == 0x8B) return Gunzip(data, path);
    return data;
}

bool IsGzipFile(const std::string& path) {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
    if (!f) return false;
    unsigned char magic[2] = {};
    return std::fread(magic, 1, 2, f.get()) == 2 && magic[0] == 0x1F && magic[1] == 0x8B;
}

bool LooksLikeCapture(ByteSpan head) {
    if (head.size() < 4) return false;
    const std::uint32_t le = ByteReader(head).U32Le();
    return le == 0xA1B2C3D4u || le == 0xD4C3B2A1u || le == 0xA1B23C4Du || le == 0x4D3CB2A1u ||
           le == 0x0A0D0D0Au;
}

Expected<CaptureContents> ParseCapture(ByteSpan file_bytes, const std::string& name) {
    if (!LooksLikeCapture(file_bytes)) {
        return Error{name + ": not a pcap or pcapng capture (unknown magic number)"};
    }
    // libpcap reads from a FILE*; fmemopen gives it the bytes already in memory (gunzipped).
    std::FILE* fp = fmemopen(const_cast<std::uint8_t*>(file_bytes.data()), file_bytes.size(), "rb");
    if (fp == nullptr) return Error{name + ": fmemopen: " + ErrnoText(errno)};
    char errbuf[PCAP_ERRBUF_SIZE] = {};
    pcap_t* raw = pcap_fopen_offline(fp, errbuf);
    if (raw == nullptr) {
        std::fclose(fp);  // libpcap closes the FILE only when it succeeded in opening it
        return Error{name + ": " + errbuf};
    }
    std::unique_ptr<pcap_t, PcapCloser> pcap(raw);

    CaptureStats stats;
    stats.format = ByteReader(file_bytes).U32Le() == 0x0A0D0D0Au ? "pcapng" : "pcap";
    stats.link_type = pcap_datalink(pcap.get());
    const char* link_name = pcap_datalink_val_to_name(stats.link_type);
    stats.link_type_name = link_name != nullptr ? link_name : std::to_string(stats.link_type);
    if (!LinkTypeSupported(stats.link_type)) {
        return Error{name + ": unsupported link type " + stats.link_type_name};
    }

    CaptureBuilder builder(stats.link_type);
    while (true) {
        pcap_pkthdr* header = nullptr;
        const u_char* data = nullptr;
        const int rc = pcap_next_ex(pcap.get(), &header, &data);
        if (rc == PCAP_ERROR_BREAK) break;  // end of file
        if (rc != 1) {
            // A capture cut inside a packet record: keep what came before, as a receiver would.
            stats.read_error = pcap_geterr(pcap.get());
            break;
        }
        const std::int64_t utime = static_cast<std::int64_t>(header->ts.tv_sec) * 1000000 +
                                   static_cast<std::int64_t>(header->ts.tv_usec);
        builder.AddPacket(
            utime, ByteSpan(data, header->caplen), header->caplen < header->len, stats);
    }
    return builder.Finish(std::move(stats));
}

Expected<CaptureContents> ReadCapture(const std::string& path) {
    auto bytes = ReadFileBytes(path);
    if (!bytes) return bytes.error();
    auto contents = ParseCapture(*bytes, path);
    if (contents) contents->stats.gzip = IsGzipFile(path);
    return contents;
}

}  // namespace pitmap::capture
