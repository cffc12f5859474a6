#include "sensors/network/transport.hpp"

#include <sys/stat.h>

#include <fstream>
#include <map>
#include <vector>

#include "io/capture_folder.hpp"
#include "toolkit/error.hpp"

namespace rgbd::sensors::net {

std::string control_endpoint_for(const std::string& frames_endpoint) {
    const auto colon = frames_endpoint.rfind(':');
    if (colon == std::string::npos || colon + 1 >= frames_endpoint.size())
        throw InputError("endpoint '" + frames_endpoint + "' has no port (e.g. tcp://host:5555)");
    const std::string port_text = frames_endpoint.substr(colon + 1);
    int port = 0;
    try {
        std::size_t used = 0;
        port = std::stoi(port_text, &used);
        if (used != port_text.size()) port = 0;
    } catch (...) {
        port = 0;
    }
    if (port <= 0 || port >= 65535)
        throw InputError("endpoint '" + frames_endpoint + "': port must be 1..65534");
    return frames_endpoint.substr(0, colon + 1) + std::to_string(port + 1);
}

bool curve_available() { return zmq_has("curve") != 0; }

CurveKeys read_key_file(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw IoError(path.string() + ": cannot open key file");
    std::map<std::string, std::string> values;
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
        ++number;
        if (line.empty() || line[0] == '#') continue;
        const auto eq = line.find('=');
        if (eq == std::string::npos)
            throw InputError(path.string() + ":" + std::to_string(number) + ": expected name=key");
        const std::string name = line.substr(0, eq), key = line.substr(eq + 1);
        std::uint8_t binary[32];
        if (key.size() != 40 || zmq_z85_decode(binary, key.c_str()) == nullptr)
            throw InputError(path.string() + ":" + std::to_string(number) + ": '" + name +
                             "' is not a 40-character Z85 key");
        values[name] = key;
    }
    CurveKeys k;
    for (auto [name, field] : {std::pair{"server_public", &k.server_public},
                               std::pair{"server_secret", &k.server_secret},
                               std::pair{"client_public", &k.client_public},
                               std::pair{"client_secret", &k.client_secret}}) {
        const auto it = values.find(name);
        if (it == values.end())
            throw InputError(path.string() + ": key file has no '" + std::string(name) + "'");
        *field = it->second;
    }
    return k;
}

void write_key_file(const std::filesystem::path& path) {
    if (!curve_available()) throw IoError("this libzmq has no CURVE support (zmq_has(\"curve\"))");
    char sp[41], ss[41], cp[41], cs[41];
    if (zmq_curve_keypair(sp, ss) != 0 || zmq_curve_keypair(cp, cs) != 0)
        throw IoError("cannot generate CURVE keys: " + std::string(zmq_strerror(zmq_errno())));
    const std::string text =
        "# rgbd-capture CURVE keys: give this file to the hub and its nodes only\n"
        "server_public=" +
        std::string(sp) + "\nserver_secret=" + ss + "\nclient_public=" + cp +
        "\nclient_secret=" + cs + "\n";
    const mode_t old = ::umask(077);
    try {
        io::write_text_atomic(path, text);
    } catch (...) {
        ::umask(old);
        throw;
    }
    ::umask(old);
    ::chmod(path.c_str(), 0600);
}

void make_curve_server(zmq::socket_t& socket, const CurveKeys& keys) {
    socket.set(zmq::sockopt::zap_domain, "rgbd");
    socket.set(zmq::sockopt::curve_server, 1);
    socket.set(zmq::sockopt::curve_secretkey, keys.server_secret);
}

void make_curve_client(zmq::socket_t& socket, const CurveKeys& keys) {
    socket.set(zmq::sockopt::curve_serverkey, keys.server_public);
    socket.set(zmq::sockopt::curve_publickey, keys.client_public);
    socket.set(zmq::sockopt::curve_secretkey, keys.client_secret);
}

ZapAuthenticator::ZapAuthenticator(zmq::context_t& context, const std::string& allowed_public)
    : socket_(context, zmq::socket_type::rep) {
    allowed_.resize(32);
    if (allowed_public.size() != 40 ||
        zmq_z85_decode(reinterpret_cast<std::uint8_t*>(allowed_.data()), allowed_public.c_str()) ==
            nullptr)
        throw InputError("ZAP: the allowed client key is not a Z85 key");
    socket_.set(zmq::sockopt::linger, 0);
    socket_.bind("inproc://zeromq.zap.01");
    thread_ = std::thread([this] { run(); });
}

ZapAuthenticator::~ZapAuthenticator() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
}

void ZapAuthenticator::run() {
    while (!stop_) {
        zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
        try {
            if (zmq::poll(&item, 1, std::chrono::milliseconds(100)) == 0) continue;
            std::vector<zmq::message_t> parts;
            zmq::message_t part;
            do {
                if (!socket_.recv(part, zmq::recv_flags::none)) break;
                parts.push_back(std::move(part));
                part = zmq::message_t();
            } while (parts.back().more());
            // version, request id, domain, address, identity, mechanism, credentials...
            bool ok = parts.size() >= 7 && parts[5].to_string() == "CURVE" &&
                      parts[6].size() == 32 &&
                      std::string(static_cast<const char*>(parts[6].data()), 32) == allowed_;
            (ok ? accepted_ : refused_)++;
            const std::string request_id = parts.size() > 1 ? parts[1].to_string() : "";
            socket_.send(zmq::str_buffer("1.0"), zmq::send_flags::sndmore);
            socket_.send(zmq::buffer(request_id), zmq::send_flags::sndmore);
            socket_.send(zmq::buffer(std::string(ok ? "200" : "400")), zmq::send_flags::sndmore);
            socket_.send(zmq::buffer(std::string(ok ? "OK" : "unknown client key")),
                         zmq::send_flags::sndmore);
            socket_.send(zmq::str_buffer(""), zmq::send_flags::sndmore);
            socket_.send(zmq::str_buffer(""), zmq::send_flags::none);
        } catch (const zmq::error_t&) {
            if (stop_) break;
        }
    }
}

}  // namespace rgbd::sensors::net
