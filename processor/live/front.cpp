// SPDX-License-Identifier: MIT
#include "processor/live/front.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <unordered_map>

#include "processor/live/http_rules.hpp"

namespace pitmap::proc::live {

namespace {

std::int64_t SteadyUs() {
    return std::chrono::duration_cast<std::chrono::microseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

std::int64_t Us(double s) {
    return static_cast<std::int64_t>(std::llround(s * 1e6));
}

const char* StatusText(int status) {
    switch (status) {
        case 400:
            return "Bad Request";
        case 408:
            return "Request Timeout";
        case 413:
            return "Content Too Large";
        case 431:
            return "Request Header Fields Too Large";
        case 500:
            return "Internal Server Error";
        case 501:
            return "Not Implemented";
        case 503:
            return "Service Unavailable";
        default:
            return "Error";
    }
}

// The front's own answers: the same JSON error shape and security headers as the handlers'.
std::string ErrorResponse(int status, const std::string& reason) {
    const std::string body = nlohmann::json{{"error", reason}}.dump(
        -1, ' ', false, nlohmann::json::error_handler_t::replace);
    std::string r = "HTTP/1.1 " + std::to_string(status) + " " + StatusText(status) + "\r\n";
    r += "Content-Type: application/vnd.pitmap+json\r\n";
    r += "Content-Length: " + std::to_string(body.size()) + "\r\n";
    r += "Cache-Control: no-store\r\nConnection: close\r\n";
    if (status == 503) r += "Retry-After: 1\r\n";
    for (const auto& h : SecurityHeaders()) r += std::string(h.name) + ": " + h.value + "\r\n";
    return r + "\r\n" + body;
}

std::string PeerIp(const sockaddr_storage& a, int* port) {
    char buf[INET6_ADDRSTRLEN] = {};
    if (a.ss_family == AF_INET) {
        const auto* v4 = reinterpret_cast<const sockaddr_in*>(&a);
        inet_ntop(AF_INET, &v4->sin_addr, buf, sizeof(buf));
        *port = ntohs(v4->sin_port);
    } else if (a.ss_family == AF_INET6) {
        const auto* v6 = reinterpret_cast<const sockaddr_in6*>(&a);
        inet_ntop(AF_INET6, &v6->sin6_addr, buf, sizeof(buf));
        *port = ntohs(v6->sin6_port);
    }
    return buf;
}

enum class ConnState { kReading, kProcessing, kWriting };

struct Conn {
    int fd = -1;
    std::uint64_t id = 0;
    std::string peer_ip;
    int peer_port = 0;
    ConnState state = ConnState::kReading;
    std::string in;
    std::string out;
    std::size_t out_pos = 0;
    // kReading: when it began waiting for this request (accept, or the previous answer
    // written); the eviction order. header_seen: its header is complete (the body deadline).
    std::int64_t waiting_since_us = 0;
    std::int64_t deadline_us = 0;
    bool header_seen = false;
    bool close_after = false;
    bool peer_eof = false;
    int requests = 0;
    std::uint32_t events = 0;  // what epoll watches now
};

}  // namespace

std::vector<std::string> ConnectionLimits::Validate() const {
    std::vector<std::string> p;
    if (max_connections < 1 || max_connections > 100'000)
        p.push_back("live: max_connections must lie in [1, 100000]");
    if (max_connections_per_address < 1 || max_connections_per_address > max_connections)
        p.push_back("live: max_connections_per_address must lie in [1, max_connections]");
    for (const auto& [name, v] : {std::pair{"header_timeout_s", header_timeout_s},
                                  std::pair{"body_timeout_s", body_timeout_s},
                                  std::pair{"idle_timeout_s", idle_timeout_s},
                                  std::pair{"write_timeout_s", write_timeout_s}}) {
        if (!(v > 0 && v <= 3600))
            p.push_back(std::string("live: ") + name + " must lie in (0, 3600] s");
    }
    if (max_header_bytes < 1024 || max_header_bytes > 1'048'576)
        p.push_back("live: max_header_bytes must lie in [1024, 1048576]");
    if (max_body_bytes > 16'777'216) p.push_back("live: max_body_bytes must be at most 16 MiB");
    if (max_requests_per_connection < 1)
        p.push_back("live: max_requests_per_connection must be >= 1");
    if (worker_threads < 1 || worker_threads > 64)
        p.push_back("live: worker_threads must lie in [1, 64]");
    return p;
}

struct HttpFront::Impl {
    ConnectionLimits limits;
    FrontHandler handler;
    int listen_fd = -1;
    int epoll_fd = -1;
    int wake_fd = -1;  // eventfd: answers ready, or stop
    std::atomic<bool> stopping{false};
    std::thread loop;
    std::vector<std::thread> workers;

    // Owned by the loop thread.
    std::unordered_map<int, Conn> conns;
    std::unordered_map<std::string, std::size_t> per_address;
    std::uint64_t next_id = 1;
    std::int64_t accept_paused_until_us = 0;

    // Loop -> workers, workers -> loop.
    struct Job {
        int fd;
        std::uint64_t id;
        FrontRequest request;
    };
    struct Done {
        int fd;
        std::uint64_t id;
        FrontAnswer answer;
    };
    std::mutex jobs_mutex;
    std::condition_variable jobs_cv;
    std::deque<Job> jobs;
    bool workers_stop = false;
    std::mutex done_mutex;
    std::vector<Done> done;

    struct Counters {
        std::atomic<std::int64_t> accepted{0}, open{0}, requests{0}, evicted{0}, refused{0},
            header_timeouts{0}, idle_closed{0}, write_timeouts{0}, bad_requests{0},
            accept_failures{0};
    } counters;

    void Wake() {
        const std::uint64_t one = 1;
        [[maybe_unused]] const ssize_t n = ::write(wake_fd, &one, sizeof(one));
    }

    void Watch(Conn& c, std::uint32_t events) {
        if (c.events == events) return;
        epoll_event ev{};
        ev.events = events;
        ev.data.fd = c.fd;
        epoll_ctl(epoll_fd, EPOLL_CTL_MOD, c.fd, &ev);
        c.events = events;
    }

    void Close(int fd) {
        auto it = conns.find(fd);
        if (it == conns.end()) return;
        auto pa = per_address.find(it->second.peer_ip);
        if (pa != per_address.end() && --pa->second == 0) per_address.erase(pa);
        epoll_ctl(epoll_fd, EPOLL_CTL_DEL, fd, nullptr);
        ::close(fd);
        conns.erase(it);
        counters.open.fetch_sub(1);
    }

    // A last answer of the front's own: best effort (the socket buffer of a fresh connection
    // takes it whole), then the connection closes.
    void AnswerAndClose(int fd, int status, const std::string& reason) {
        const std::string r = ErrorResponse(status, reason);
        [[maybe_unused]] const ssize_t n = ::send(fd, r.data(), r.size(), MSG_NOSIGNAL);
        Close(fd);
    }

    // The connection waiting for its request the longest, of `ip` ("" = of any address).
    int OldestWaiting(const std::string& ip) const {
        int best = -1;
        std::int64_t since = 0;
        for (const auto& [fd, c] : conns) {
            if (c.state != ConnState::kReading || (!ip.empty() && c.peer_ip != ip)) continue;
            if (best < 0 || c.waiting_since_us < since) {
                best = fd;
                since = c.waiting_since_us;
            }
        }
        return best;
    }

    // Makes room for one more connection from `ip`; false when every candidate is busy.
    bool MakeRoom(const std::string& ip) {
        auto pa = per_address.find(ip);
        if (pa != per_address.end() && pa->second >= limits.max_connections_per_address) {
            const int fd = OldestWaiting(ip);
            if (fd < 0) return false;
            Close(fd);
            counters.evicted.fetch_add(1);
        }
        if (conns.size() >= limits.max_connections) {
            const int fd = OldestWaiting("");
            if (fd < 0) return false;
            Close(fd);
            counters.evicted.fetch_add(1);
        }
        return true;
    }

    void AcceptAll(std::int64_t now) {
        for (int k = 0; k < 256; ++k) {
            sockaddr_storage addr{};
            socklen_t len = sizeof(addr);
            const int fd = accept4(
                listen_fd, reinterpret_cast<sockaddr*>(&addr), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
            if (fd < 0) {
                if (errno == EAGAIN || errno == EWOULDBLOCK) return;
                if (errno == EINTR || errno == ECONNABORTED) continue;
                counters.accept_failures.fetch_add(1);
                // Out of descriptors (EMFILE, ENFILE) or memory: a waiting connection gives
                // its descriptor up, else the listener rests for 100 ms (level-triggered, it
                // would wake the loop at once again).
                const int victim = OldestWaiting("");
                if (victim >= 0) {
                    Close(victim);
                    counters.evicted.fetch_add(1);
                    continue;
                }
                epoll_event ev{};
                ev.data.fd = listen_fd;
                epoll_ctl(epoll_fd, EPOLL_CTL_MOD, listen_fd, &ev);
                accept_paused_until_us = now + 100'000;
                return;
            }
            int port = 0;
            std::string ip = PeerIp(addr, &port);
            if (!MakeRoom(ip)) {
                counters.refused.fetch_add(1);
                const std::string r = ErrorResponse(503, "too many connections; try again");
                [[maybe_unused]] const ssize_t n = ::send(fd, r.data(), r.size(), MSG_NOSIGNAL);
                ::close(fd);
                continue;
            }
            const int one = 1;
            setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
            Conn c;
            c.fd = fd;
            c.id = next_id++;
            c.peer_ip = ip;
            c.peer_port = port;
            c.waiting_since_us = now;
            c.deadline_us = now + Us(limits.header_timeout_s);
            c.events = EPOLLIN;
            epoll_event ev{};
            ev.events = EPOLLIN;
            ev.data.fd = fd;
            if (epoll_ctl(epoll_fd, EPOLL_CTL_ADD, fd, &ev) != 0) {
                ::close(fd);
                continue;
            }
            ++per_address[ip];
            conns.emplace(fd, std::move(c));
            counters.accepted.fetch_add(1);
            counters.open.fetch_add(1);
        }
    }

    std::size_t InputCap() const { return limits.max_header_bytes + limits.max_body_bytes + 4096; }

    void OnReadable(Conn& c, std::int64_t now) {
        char buf[16384];
        while (c.in.size() < InputCap()) {
            const std::size_t want = std::min(sizeof(buf), InputCap() - c.in.size());
            const ssize_t n = ::recv(c.fd, buf, want, 0);
            if (n > 0) {
                // A kept-alive connection's next request: its header deadline starts now.
                if (c.in.empty() && c.requests > 0 && !c.header_seen) {
                    c.deadline_us = now + Us(limits.header_timeout_s);
                }
                c.in.append(buf, static_cast<std::size_t>(n));
                continue;
            }
            if (n == 0) {
                c.peer_eof = true;
                break;
            }
            if (errno == EAGAIN || errno == EWOULDBLOCK) break;
            if (errno == EINTR) continue;
            Close(c.fd);
            return;
        }
        Advance(c, now);
    }

    // A reading connection with new bytes: a complete request goes to a worker.
    void Advance(Conn& c, std::int64_t now) {
        const RequestFrame f = FrameRequest(c.in, limits.max_header_bytes, limits.max_body_bytes);
        if (f.skipped > 0) c.in.erase(0, f.skipped);
        switch (f.kind) {
            case RequestFrame::Kind::kError:
                counters.bad_requests.fetch_add(1);
                AnswerAndClose(c.fd, f.status, f.reason);
                return;
            case RequestFrame::Kind::kNeedMore:
                if (c.peer_eof) {
                    Close(c.fd);
                    return;
                }
                if (f.header_bytes > 0 && !c.header_seen) {
                    c.header_seen = true;
                    c.deadline_us = now + Us(limits.body_timeout_s);
                }
                return;
            case RequestFrame::Kind::kComplete:
                break;
        }
        Job job{c.fd, c.id, {}};
        job.request.bytes = c.in.substr(0, f.total_bytes);
        c.in.erase(0, f.total_bytes);
        job.request.peer_ip = c.peer_ip;
        job.request.peer_port = c.peer_port;
        job.request.last = c.peer_eof || c.requests + 1 >= limits.max_requests_per_connection;
        c.close_after = job.request.last;
        c.state = ConnState::kProcessing;
        c.deadline_us = 0;
        Watch(c, 0);  // nothing more is read until this answer is out (no pipelining backlog)
        counters.requests.fetch_add(1);
        {
            std::lock_guard<std::mutex> lock(jobs_mutex);
            jobs.push_back(std::move(job));
        }
        jobs_cv.notify_one();
    }

    void TryWrite(Conn& c, std::int64_t now) {
        while (c.out_pos < c.out.size()) {
            const ssize_t n =
                ::send(c.fd, c.out.data() + c.out_pos, c.out.size() - c.out_pos, MSG_NOSIGNAL);
            if (n > 0) {
                c.out_pos += static_cast<std::size_t>(n);
                continue;
            }
            if (n < 0 && errno == EINTR) continue;
            if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
                Watch(c, EPOLLOUT);
                return;
            }
            Close(c.fd);
            return;
        }
        if (c.close_after) {
            Close(c.fd);
            return;
        }
        c.out.clear();
        c.out.shrink_to_fit();
        c.out_pos = 0;
        c.requests += 1;
        c.state = ConnState::kReading;
        c.header_seen = false;
        c.waiting_since_us = now;
        c.deadline_us = now + Us(c.in.empty() ? limits.idle_timeout_s : limits.header_timeout_s);
        Watch(c, EPOLLIN);
        if (!c.in.empty()) Advance(c, now);  // a request sent before this answer
    }

    void TakeAnswers(std::int64_t now) {
        std::vector<Done> ready;
        {
            std::lock_guard<std::mutex> lock(done_mutex);
            ready.swap(done);
        }
        for (auto& d : ready) {
            auto it = conns.find(d.fd);
            if (it == conns.end() || it->second.id != d.id) continue;  // closed meanwhile
            Conn& c = it->second;
            c.out = std::move(d.answer.bytes);
            c.out_pos = 0;
            c.close_after = c.close_after || d.answer.close || c.out.empty();
            c.state = ConnState::kWriting;
            c.deadline_us = now + Us(limits.write_timeout_s);
            TryWrite(c, now);
        }
    }

    // Closes what is past its deadline; the next deadline (0 = none).
    std::int64_t Expire(std::int64_t now) {
        std::vector<std::pair<int, int>> expired;  // fd, 0 idle / 1 header / 2 write
        std::int64_t next = 0;
        for (const auto& [fd, c] : conns) {
            if (c.deadline_us == 0) continue;
            if (c.deadline_us <= now) {
                const bool idle = c.state == ConnState::kReading && c.in.empty() && c.requests > 0;
                expired.emplace_back(fd, c.state == ConnState::kWriting ? 2 : idle ? 0 : 1);
            } else if (next == 0 || c.deadline_us < next) {
                next = c.deadline_us;
            }
        }
        for (const auto& [fd, why] : expired) {
            if (why == 0) {
                counters.idle_closed.fetch_add(1);
                Close(fd);
            } else if (why == 1) {
                counters.header_timeouts.fetch_add(1);
                // A connection that never sent a byte may be a browser's preconnect: closed
                // without an answer it could take for the answer to a request.
                if (conns.at(fd).in.empty()) {
                    Close(fd);
                } else {
                    AnswerAndClose(fd, 408, "request not complete in time");
                }
            } else {
                counters.write_timeouts.fetch_add(1);
                Close(fd);
            }
        }
        return next;
    }

    void Loop() {
        std::vector<epoll_event> events(512);
        std::int64_t next_deadline = 0;
        while (!stopping.load()) {
            std::int64_t now = SteadyUs();
            int timeout_ms = 1000;
            if (next_deadline > 0)
                timeout_ms = static_cast<int>(
                    std::clamp<std::int64_t>((next_deadline - now + 999) / 1000, 0, 1000));
            if (accept_paused_until_us > 0)
                timeout_ms = std::min<int>(
                    timeout_ms,
                    static_cast<int>(std::max<std::int64_t>(0, accept_paused_until_us - now) /
                                     1000));
            const int n =
                epoll_wait(epoll_fd, events.data(), static_cast<int>(events.size()), timeout_ms);
            now = SteadyUs();
            for (int k = 0; k < n; ++k) {
                const int fd = events[k].data.fd;
                const std::uint32_t ev = events[k].events;
                if (fd == listen_fd) {
                    AcceptAll(now);
                } else if (fd == wake_fd) {
                    std::uint64_t v;
                    [[maybe_unused]] const ssize_t r = ::read(wake_fd, &v, sizeof(v));
                    TakeAnswers(now);
                } else {
                    auto it = conns.find(fd);
                    if (it == conns.end()) continue;
                    Conn& c = it->second;
                    if (ev & EPOLLERR) {
                        Close(fd);
                    } else if (c.state == ConnState::kReading && (ev & (EPOLLIN | EPOLLHUP))) {
                        OnReadable(c, now);
                    } else if (c.state == ConnState::kWriting && (ev & (EPOLLOUT | EPOLLHUP))) {
                        TryWrite(c, now);
                    } else if (ev & EPOLLHUP) {
                        Close(fd);  // gone while its request runs: the answer is dropped
                    }
                }
            }
            if (accept_paused_until_us > 0 && now >= accept_paused_until_us) {
                accept_paused_until_us = 0;
                epoll_event ev{};
                ev.events = EPOLLIN;
                ev.data.fd = listen_fd;
                epoll_ctl(epoll_fd, EPOLL_CTL_MOD, listen_fd, &ev);
            }
            next_deadline = Expire(now);
        }
        while (!conns.empty()) Close(conns.begin()->first);
    }

    void Work() {
        for (;;) {
            Job job;
            {
                std::unique_lock<std::mutex> lock(jobs_mutex);
                jobs_cv.wait(lock, [this] { return workers_stop || !jobs.empty(); });
                if (workers_stop) return;
                job = std::move(jobs.front());
                jobs.pop_front();
            }
            Done d{job.fd, job.id, {}};
            try {
                d.answer = handler(job.request);
            } catch (const std::exception& e) {
                d.answer = {ErrorResponse(500, std::string("internal error: ") + e.what()), true};
            }
            {
                std::lock_guard<std::mutex> lock(done_mutex);
                done.push_back(std::move(d));
            }
            Wake();
        }
    }
};

HttpFront::HttpFront(const ConnectionLimits& limits, FrontHandler handler)
    : impl_(std::make_unique<Impl>()) {
    impl_->limits = limits;
    impl_->handler = std::move(handler);
}

HttpFront::~HttpFront() {
    Stop();
}

Status HttpFront::Start(const std::string& address, int port) {
    Impl& m = *impl_;
    const std::string where = address + ":" + (port == 0 ? "any port" : std::to_string(port));
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    addrinfo* res = nullptr;
    if (getaddrinfo(address.c_str(), std::to_string(port).c_str(), &hints, &res) != 0 || !res)
        return Error{"cannot bind " + where + " (not an address of this machine)"};
    std::string why = "in use, or not an address of this machine";
    for (addrinfo* a = res; a && m.listen_fd < 0; a = a->ai_next) {
        const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
        if (fd < 0) continue;
        const int one = 1;
        setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
        if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, SOMAXCONN) == 0) {
            m.listen_fd = fd;
        } else {
            why = std::strerror(errno);
            ::close(fd);
        }
    }
    freeaddrinfo(res);
    if (m.listen_fd < 0) return Error{"cannot bind " + where + " (" + why + ")"};
    sockaddr_storage bound{};
    socklen_t len = sizeof(bound);
    getsockname(m.listen_fd, reinterpret_cast<sockaddr*>(&bound), &len);
    PeerIp(bound, &port_);

    m.epoll_fd = epoll_create1(EPOLL_CLOEXEC);
    m.wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (m.epoll_fd < 0 || m.wake_fd < 0) return Error{"cannot create the HTTP event loop"};
    for (int fd : {m.listen_fd, m.wake_fd}) {
        epoll_event ev{};
        ev.events = EPOLLIN;
        ev.data.fd = fd;
        epoll_ctl(m.epoll_fd, EPOLL_CTL_ADD, fd, &ev);
    }
    for (int k = 0; k < m.limits.worker_threads; ++k) m.workers.emplace_back([&m] { m.Work(); });
    m.loop = std::thread([&m] { m.Loop(); });
    return Ok{};
}

void HttpFront::Stop() {
    Impl& m = *impl_;
    m.stopping.store(true);
    if (m.wake_fd >= 0) m.Wake();
    if (m.loop.joinable()) m.loop.join();
    {
        std::lock_guard<std::mutex> lock(m.jobs_mutex);
        m.workers_stop = true;
    }
    m.jobs_cv.notify_all();
    for (auto& w : m.workers) w.join();
    m.workers.clear();
    for (int* fd : {&m.listen_fd, &m.epoll_fd, &m.wake_fd}) {
        if (*fd >= 0) ::close(*fd);
        *fd = -1;
    }
}

FrontStats HttpFront::stats() const {
    const auto& c = impl_->counters;
    FrontStats s;
    s.accepted = c.accepted.load();
    s.open = c.open.load();
    s.requests = c.requests.load();
    s.evicted = c.evicted.load();
    s.refused = c.refused.load();
    s.header_timeouts = c.header_timeouts.load();
    s.idle_closed = c.idle_closed.load();
    s.write_timeouts = c.write_timeouts.load();
    s.bad_requests = c.bad_requests.load();
    s.accept_failures = c.accept_failures.load();
    return s;
}

}  // namespace pitmap::proc::live
