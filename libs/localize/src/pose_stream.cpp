#include "lookup/localize/pose_stream.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace lookup::localize {

namespace {

// Bytes one TCP client may have waiting before its messages are dropped: a few seconds of
// poses, so a client that pauses briefly loses nothing, one that never reads is bounded.
constexpr std::size_t kMaxPendingBytes = 256 * 1024;

std::string peerName(const sockaddr_storage& addr) {
    char host[NI_MAXHOST] = "?", port[NI_MAXSERV] = "?";
    getnameinfo(reinterpret_cast<const sockaddr*>(&addr), sizeof addr, host, sizeof host, port,
                sizeof port, NI_NUMERICHOST | NI_NUMERICSERV);
    return std::string(host) + ":" + port;
}

struct ParsedUrl {
    bool tcp = false;
    std::string host, port;
};

ParsedUrl parseUrl(const std::string& url) {
    const auto fail = [&url](const std::string& why) {
        return std::runtime_error("--publish " + url + ": " + why);
    };
    ParsedUrl p;
    const auto scheme_end = url.find("://");
    const std::string scheme = scheme_end == std::string::npos ? "" : url.substr(0, scheme_end);
    if (scheme != "udp" && scheme != "tcp") throw fail("not udp://HOST:PORT or tcp://HOST:PORT");
    p.tcp = scheme == "tcp";
    const std::string rest = url.substr(scheme_end + 3);
    const auto colon = rest.rfind(':');
    if (colon == std::string::npos || colon == 0) throw fail("no HOST:PORT after " + scheme);
    p.host = rest.substr(0, colon);
    if (p.host.size() > 2 && p.host.front() == '[' && p.host.back() == ']') {
        p.host = p.host.substr(1, p.host.size() - 2);  // [IPv6 address]
    }
    p.port = rest.substr(colon + 1);
    const bool digits = !p.port.empty() && p.port.size() <= 5 &&
                        std::all_of(p.port.begin(), p.port.end(), ::isdigit);
    const int port = digits ? std::stoi(p.port) : -1;
    if (port < 0 || port > 65535 || (port == 0 && !p.tcp)) {
        throw fail("port '" + p.port + "' is not a number in 1-65535");
    }
    return p;
}

}  // namespace

double PoseStream::unixTime() {
    using namespace std::chrono;
    return duration<double>(system_clock::now().time_since_epoch()).count();
}

PoseStream::PoseStream(const std::string& url, std::size_t queue_capacity)
    : url_(url), capacity_(std::max<std::size_t>(1, queue_capacity)) {
    const ParsedUrl p = parseUrl(url);
    tcp_ = p.tcp;
    addrinfo hints{};
    hints.ai_socktype = tcp_ ? SOCK_STREAM : SOCK_DGRAM;
    hints.ai_flags = tcp_ ? AI_PASSIVE : 0;
    addrinfo* found = nullptr;
    // A name's IPv4 address first ("localhost" may list ::1 first, where a consumer on
    // 127.0.0.1 would hear nothing); IPv6 for names and literals that have only that.
    hints.ai_family = AF_INET;
    int rc = getaddrinfo(p.host.c_str(), p.port.c_str(), &hints, &found);
    if (rc != 0) {
        hints.ai_family = AF_UNSPEC;
        rc = getaddrinfo(p.host.c_str(), p.port.c_str(), &hints, &found);
    }
    if (rc != 0) {
        throw std::runtime_error("--publish " + url + ": cannot resolve '" + p.host +
                                 "': " + gai_strerror(rc));
    }
    std::string error = "no address";
    for (addrinfo* a = found; a != nullptr && fd_ < 0; a = a->ai_next) {
        const int fd = socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK, a->ai_protocol);
        if (fd < 0) {
            error = std::strerror(errno);
            continue;
        }
        if (tcp_) {
            const int yes = 1;
            setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
            if (bind(fd, a->ai_addr, a->ai_addrlen) != 0 || listen(fd, 8) != 0) {
                error = std::string("cannot bind: ") + std::strerror(errno);
                ::close(fd);
                continue;
            }
            sockaddr_storage bound{};
            socklen_t len = sizeof bound;
            getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &len);
            port_ = std::stoi(peerName(bound).substr(peerName(bound).rfind(':') + 1));
        } else {
            const auto* bytes = reinterpret_cast<const unsigned char*>(a->ai_addr);
            udp_dest_.assign(bytes, bytes + a->ai_addrlen);
            port_ = std::stoi(p.port);
        }
        fd_ = fd;
    }
    freeaddrinfo(found);
    if (fd_ < 0) throw std::runtime_error("--publish " + url + ": " + error);
    sender_ = std::thread([this] { senderLoop(); });
}

PoseStream::~PoseStream() { close(); }

void PoseStream::push(nlohmann::json message, double t_arrival_s) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (stopping_) return;
        if (queue_.size() >= capacity_) {
            ++stats_.dropped_queue_full;
            return;
        }
        queue_.push_back({std::move(message), t_arrival_s});
        ++stats_.queued;
    }
    wake_.notify_one();
}

bool PoseStream::waitForClient(double timeout_s) {
    if (!tcp_) return true;
    std::unique_lock<std::mutex> lock(mutex_);
    return client_arrived_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                                    [this] { return stats_.clients_now > 0; });
}

void PoseStream::close(double drain_timeout_s) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!sender_.joinable()) return;
        stopping_ = true;
        drain_until_s_ = unixTime() + drain_timeout_s;
    }
    wake_.notify_one();
    sender_.join();
    for (auto& c : clients_) ::close(c.fd);
    clients_.clear();
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
}

PoseStreamStats PoseStream::stats() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
}

void PoseStream::senderLoop() {
    for (;;) {
        std::deque<Item> batch;
        bool stop = false;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            // Wakes at least every 50 ms to accept clients and notice disconnections.
            wake_.wait_for(lock, std::chrono::milliseconds(50),
                           [this] { return stopping_ || !queue_.empty(); });
            batch.swap(queue_);
            stop = stopping_;
        }
        if (tcp_) {
            acceptClients();
            pollClients();
        }
        for (auto& item : batch) {
            const double now = unixTime();
            item.message["t_sent"] = now;
            if (item.t_arrival_s >= 0) item.message["latency_ms"] = 1e3 * (now - item.t_arrival_s);
            deliver(item.message.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) +
                    "\n");
        }
        logDrops();
        if (!stop) continue;
        // Drain: give slow clients until the deadline to take what they were sent.
        while (unixTime() < drain_until_s_) {
            std::vector<pollfd> fds;
            for (const auto& c : clients_) {
                if (c.fd >= 0 && !c.pending.empty()) fds.push_back({c.fd, POLLOUT, 0});
            }
            if (fds.empty()) break;
            poll(fds.data(), fds.size(), 10);
            for (auto& c : clients_) flushClient(c);
        }
        return;
    }
}

void PoseStream::acceptClients() {
    for (;;) {
        sockaddr_storage addr{};
        socklen_t len = sizeof addr;
        const int fd = accept4(fd_, reinterpret_cast<sockaddr*>(&addr), &len, SOCK_NONBLOCK);
        if (fd < 0) return;  // EAGAIN: nobody waiting (other errors: retried next wake-up)
        Client c;
        c.fd = fd;
        c.name = peerName(addr);
        std::fprintf(stderr, "lookup-localize: %s: client %s connected\n", url_.c_str(),
                     c.name.c_str());
        clients_.push_back(std::move(c));
        {
            std::lock_guard<std::mutex> lock(mutex_);
            ++stats_.clients_connected;
            stats_.clients_now = clients_.size();
        }
        client_arrived_.notify_all();
    }
}

void PoseStream::pollClients() {
    // Clients send nothing; reading tells a closed connection (0) from an idle one (EAGAIN).
    char buf[512];
    for (std::size_t k = clients_.size(); k-- > 0;) {
        const ssize_t n = recv(clients_[k].fd, buf, sizeof buf, MSG_DONTWAIT);
        if (n == 0) {
            dropClient(k, "disconnected");
        } else if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
            dropClient(k, std::string("disconnected: ") + std::strerror(errno));
        }
    }
}

void PoseStream::deliver(const std::string& line) {
    if (!tcp_) {
        const ssize_t n =
            sendto(fd_, line.data(), line.size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                   reinterpret_cast<const sockaddr*>(udp_dest_.data()), udp_dest_.size());
        const int error = errno;
        bool first_error = false;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (n == static_cast<ssize_t>(line.size())) {
                ++stats_.sent;
            } else {
                first_error = stats_.send_errors++ == 0;
            }
        }
        if (first_error) {
            std::fprintf(stderr, "lookup-localize: %s: send failed: %s (counted, not retried)\n",
                         url_.c_str(), std::strerror(error));
        }
        return;
    }
    std::size_t handed = 0, dropped = 0;
    for (auto& c : clients_) {
        if (c.pending.size() + line.size() > kMaxPendingBytes) {
            ++dropped;
            if (!c.slow_logged) {
                std::fprintf(stderr,
                             "lookup-localize: %s: client %s is not reading: dropping its "
                             "messages until it catches up\n",
                             url_.c_str(), c.name.c_str());
                c.slow_logged = true;
            }
            continue;
        }
        c.pending += line;
        ++handed;
    }
    for (auto& c : clients_) flushClient(c);
    for (std::size_t k = clients_.size(); k-- > 0;) {
        if (clients_[k].fd < 0) dropClient(k, "");
    }
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.sent += handed;
    stats_.dropped_slow_client += dropped;
}

void PoseStream::flushClient(Client& c) {
    while (c.fd >= 0 && !c.pending.empty()) {
        const ssize_t n =
            send(c.fd, c.pending.data(), c.pending.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
        if (n > 0) {
            c.pending.erase(0, static_cast<std::size_t>(n));
        } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
            return;
        } else {
            std::fprintf(stderr, "lookup-localize: %s: client %s disconnected: %s\n", url_.c_str(),
                         c.name.c_str(), std::strerror(errno));
            ::close(c.fd);
            c.fd = -1;  // removed by the caller (dropClient with an empty reason)
            return;
        }
    }
    if (c.fd >= 0 && c.pending.empty() && c.slow_logged) {
        std::fprintf(stderr, "lookup-localize: %s: client %s caught up\n", url_.c_str(),
                     c.name.c_str());
        c.slow_logged = false;
    }
}

void PoseStream::dropClient(std::size_t k, const std::string& why) {
    Client& c = clients_[k];
    if (!why.empty()) {
        std::fprintf(stderr, "lookup-localize: %s: client %s %s\n", url_.c_str(), c.name.c_str(),
                     why.c_str());
    }
    if (c.fd >= 0) ::close(c.fd);
    clients_.erase(clients_.begin() + static_cast<long>(k));
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.clients_disconnected;
    stats_.clients_now = clients_.size();
}

void PoseStream::logDrops() {
    // Printed outside the lock: a blocked stderr must not block push().
    PoseStreamStats s;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        s = stats_;
    }
    const std::size_t dropped = s.dropped_queue_full + s.dropped_slow_client;
    if (dropped == drops_logged_ || unixTime() - last_drop_log_s_ < 1.0) return;
    std::fprintf(stderr,
                 "lookup-localize: %s: %zu messages dropped so far (%zu queue full, %zu for "
                 "clients not reading)\n",
                 url_.c_str(), dropped, s.dropped_queue_full, s.dropped_slow_client);
    drops_logged_ = dropped;
    last_drop_log_s_ = unixTime();
}

}  // namespace lookup::localize
