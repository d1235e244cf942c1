#pragma once
// The pose stream for the vehicle's controller (docs/run-format.md, "Pose stream"): every
// frame's result and the health messages as JSON objects, one per UDP datagram
// (udp://HOST:PORT) or one per line to every client of a TCP server (tcp://HOST:PORT).
//
// The frame loop only pushes into a bounded queue; a sender thread serialises and sends with
// non-blocking sockets. A full queue, or a TCP client that does not read, loses messages
// (counted) rather than delaying a frame; a client that disconnects is dropped and logged.

#include <nlohmann/json.hpp>

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace lookup::localize {

/// Counters of a stream, for the log, the health messages and timing.json.
struct PoseStreamStats {
    std::size_t queued = 0;               ///< messages accepted into the queue
    std::size_t sent = 0;                 ///< UDP datagrams sent / TCP lines handed to a client
    std::size_t dropped_queue_full = 0;   ///< lost because the queue was full
    std::size_t dropped_slow_client = 0;  ///< lost for one TCP client that did not read
    std::size_t send_errors = 0;          ///< UDP sends the network refused
    std::size_t clients_connected = 0;    ///< TCP clients accepted so far
    std::size_t clients_disconnected = 0;
    std::size_t clients_now = 0;  ///< TCP clients connected at present
};

class PoseStream {
  public:
    /// Opens `url` (udp://HOST:PORT or tcp://HOST:PORT; HOST a name or address, PORT 1-65535,
    /// or 0 for tcp: any free port) and starts the sender thread. At most `queue_capacity`
    /// messages wait. Throws std::runtime_error naming the URL and the reason when it cannot
    /// be parsed, resolved or bound.
    explicit PoseStream(const std::string& url, std::size_t queue_capacity = 256);
    /// Sends what is queued (for at most `drain_timeout_s`, see close) and closes the sockets.
    ~PoseStream();
    PoseStream(const PoseStream&) = delete;
    PoseStream& operator=(const PoseStream&) = delete;

    /// Queues one message; never blocks on the network. `t_arrival_s` (UNIX time, or < 0):
    /// when the frame reached the localiser; the sender adds "t_sent" (UNIX time [s]) and,
    /// with an arrival time, "latency_ms" = t_sent - t_arrival.
    void push(nlohmann::json message, double t_arrival_s = -1);

    /// tcp: waits up to `timeout_s` until at least one client is connected. Returns whether
    /// one is (udp: always true).
    bool waitForClient(double timeout_s);

    /// Stops the sender after it sent what is queued (waiting at most `drain_timeout_s` for
    /// slow TCP clients), then closes the sockets. Idempotent.
    void close(double drain_timeout_s = 1.0);

    PoseStreamStats stats() const;
    const std::string& url() const { return url_; }
    /// The bound TCP port (useful with port 0) or the UDP destination port.
    int port() const { return port_; }

    /// UNIX time now [s], the clock of t_sent and t_arrival.
    static double unixTime();

  private:
    struct Client {
        int fd = -1;
        std::string name;     ///< peer address:port, for the log
        std::string pending;  ///< bytes not yet taken by the socket (whole lines appended)
        bool slow_logged = false;
    };
    struct Item {
        nlohmann::json message;
        double t_arrival_s;
    };
    void senderLoop();
    void acceptClients();
    void pollClients();
    void deliver(const std::string& line);
    void flushClient(Client& c);
    void dropClient(std::size_t k, const std::string& why);
    void logDrops();

    std::string url_;
    bool tcp_ = false;
    int port_ = 0;
    int fd_ = -1;                          ///< UDP socket, or the TCP listening socket
    std::vector<unsigned char> udp_dest_;  ///< sockaddr of the UDP destination
    std::size_t capacity_;

    mutable std::mutex mutex_;
    std::condition_variable wake_;
    std::condition_variable client_arrived_;
    std::deque<Item> queue_;
    bool stopping_ = false;
    double drain_until_s_ = 0;
    PoseStreamStats stats_;
    std::size_t drops_logged_ = 0;  ///< drops already logged (at most once a second)
    double last_drop_log_s_ = 0;
    std::vector<Client> clients_;  ///< sender thread only
    std::thread sender_;
};

}  // namespace lookup::localize
