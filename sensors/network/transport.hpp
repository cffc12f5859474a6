// ZeroMQ plumbing shared by rgbd-node and rgbd-capture: endpoints, CURVE keys and the ZAP
// authenticator that makes a hub with a key refuse nodes that do not hold the key file.
// Key file: four lines "server_public=", "server_secret=", "client_public=", "client_secret="
// with Z85 keys (40 characters each), made by rgbd-capture --make-key FILE. Hub and nodes get
// the same file; the hub accepts only clients proving the client key of the file.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>
#include <thread>
#include <zmq.hpp>

namespace rgbd::sensors::net {

/// The control endpoint paired with a frame endpoint: same address, port + 1
/// ("tcp://hub:5555" -> "tcp://hub:5556"; "tcp://*:5555" -> "tcp://*:5556").
/// Throws InputError for an endpoint without a numeric port.
std::string control_endpoint_for(const std::string& frames_endpoint);

struct CurveKeys {
    std::string server_public, server_secret, client_public, client_secret;  ///< Z85
};

/// zmq_has("curve"): libzmq was built with CURVE (libsodium).
bool curve_available();
/// Reads a key file; throws InputError/IoError naming the file and the bad line.
CurveKeys read_key_file(const std::filesystem::path& path);
/// Generates fresh keys and writes them to `path` (mode 0600, atomically). Throws IoError.
void write_key_file(const std::filesystem::path& path);
/// Hub side: the socket is a CURVE server with the file's server key.
void make_curve_server(zmq::socket_t& socket, const CurveKeys& keys);
/// Node side: the socket authenticates to the hub with the file's client key.
void make_curve_client(zmq::socket_t& socket, const CurveKeys& keys);

/// ZAP handler (RFC 27) on a thread: accepts CURVE clients whose public key is
/// `allowed_client_public` (Z85), refuses every other. Must exist before the server sockets
/// bind.
class ZapAuthenticator {
public:
    ZapAuthenticator(zmq::context_t& context, const std::string& allowed_client_public);
    ~ZapAuthenticator();
    ZapAuthenticator(const ZapAuthenticator&) = delete;
    ZapAuthenticator& operator=(const ZapAuthenticator&) = delete;
    std::int64_t accepted() const { return accepted_; }
    std::int64_t refused() const { return refused_; }

private:
    void run();
    zmq::socket_t socket_;
    std::string allowed_;  ///< 32 binary bytes
    std::atomic<bool> stop_{false};
    std::atomic<std::int64_t> accepted_{0}, refused_{0};
    std::thread thread_;
};

}  // namespace rgbd::sensors::net
