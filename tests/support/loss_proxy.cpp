// rgbd_test_loss_proxy: a ZeroMQ-level loss/delay proxy for the capture network tests (kernel
// netem is not available on the CI kernels). It sits between nodes and the hub, typically in
// the root namespace between two network namespaces the test creates: it listens where the
// nodes connect (--front, frames on PORT and control on PORT + 1) and connects to the hub
// (--back), holds every message for --delay-ms, and drops each with probability --loss, in
// both directions of the control channel and on the frame channel.
//   rgbd_test_loss_proxy --front tcp://10.77.2.1:5555 --back tcp://10.77.1.2:5555
//                        --delay-ms 200 --loss 0.1 [--seed 1] [--seconds 60]
#include <chrono>
#include <cstdlib>
#include <deque>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>
#include <zmq.hpp>

#include "sensors/network/transport.hpp"

namespace {

using Clock = std::chrono::steady_clock;

struct Held {
    Clock::time_point release;
    int target;      // 0 = hub frames, 1 = hub control (dealer of `id`), 2 = node control
    std::string id;  // node identity at the front router
    zmq::message_t data;
};

}  // namespace

int main(int argc, char** argv) {
    std::map<std::string, std::string> a;
    for (int i = 1; i + 1 < argc; i += 2) a[argv[i]] = argv[i + 1];
    if (!a.count("--front") || !a.count("--back")) {
        std::cerr << "usage: rgbd_test_loss_proxy --front ENDPOINT --back ENDPOINT "
                     "[--delay-ms 200] [--loss 0.1] [--seed 1] [--seconds 120]\n";
        return 2;
    }
    const auto delay = std::chrono::microseconds(static_cast<long>(
        std::atof(a.count("--delay-ms") ? a["--delay-ms"].c_str() : "200") * 1e3));
    const double loss = std::atof(a.count("--loss") ? a["--loss"].c_str() : "0.1");
    const double seconds = std::atof(a.count("--seconds") ? a["--seconds"].c_str() : "120");
    std::mt19937 rng(
        static_cast<unsigned>(std::atoi(a.count("--seed") ? a["--seed"].c_str() : "1")));
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    namespace net = rgbd::sensors::net;

    zmq::context_t context(1);
    zmq::socket_t front_frames(context, zmq::socket_type::pull);
    zmq::socket_t front_control(context, zmq::socket_type::router);
    zmq::socket_t back_frames(context, zmq::socket_type::push);
    for (zmq::socket_t* s : {&front_frames, &front_control, &back_frames})
        s->set(zmq::sockopt::linger, 0);
    front_frames.bind(a["--front"]);
    front_control.bind(net::control_endpoint_for(a["--front"]));
    back_frames.connect(a["--back"]);
    const std::string back_control = net::control_endpoint_for(a["--back"]);
    std::map<std::string, std::unique_ptr<zmq::socket_t>> dealers;  // per node identity

    std::deque<Held> held;
    std::size_t passed = 0, dropped = 0;
    const auto end = Clock::now() + std::chrono::duration<double>(seconds);
    const auto hold = [&](int target, const std::string& id, zmq::message_t&& m) {
        if (uni(rng) < loss) {
            ++dropped;
            return;
        }
        held.push_back({Clock::now() + delay, target, id, std::move(m)});
    };
    while (Clock::now() < end) {
        std::vector<zmq::pollitem_t> items = {{front_frames.handle(), 0, ZMQ_POLLIN, 0},
                                              {front_control.handle(), 0, ZMQ_POLLIN, 0}};
        std::vector<std::string> ids;
        for (auto& [id, d] : dealers) {
            items.push_back({d->handle(), 0, ZMQ_POLLIN, 0});
            ids.push_back(id);
        }
        auto timeout = std::chrono::milliseconds(50);
        if (!held.empty()) {
            const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(
                held.front().release - Clock::now());
            timeout = std::max(std::chrono::milliseconds(0), std::min(timeout, wait));
        }
        zmq::poll(items, timeout);
        zmq::message_t m;
        while (front_frames.recv(m, zmq::recv_flags::dontwait)) hold(0, "", std::move(m));
        zmq::message_t id;
        while (front_control.recv(id, zmq::recv_flags::dontwait)) {
            if (!front_control.recv(m, zmq::recv_flags::none)) break;
            const std::string key = id.to_string();
            if (!dealers.count(key)) {
                auto d = std::make_unique<zmq::socket_t>(context, zmq::socket_type::dealer);
                d->set(zmq::sockopt::linger, 0);
                d->connect(back_control);
                dealers[key] = std::move(d);
            }
            hold(1, key, std::move(m));
        }
        for (std::size_t k = 0; k < ids.size(); ++k)
            while (dealers[ids[k]]->recv(m, zmq::recv_flags::dontwait))
                hold(2, ids[k], std::move(m));
        const auto now = Clock::now();
        while (!held.empty() && held.front().release <= now) {
            Held& h = held.front();
            if (h.target == 0) {
                back_frames.send(h.data, zmq::send_flags::dontwait);
            } else if (h.target == 1) {
                dealers[h.id]->send(h.data, zmq::send_flags::dontwait);
            } else {
                front_control.send(zmq::buffer(h.id), zmq::send_flags::sndmore);
                front_control.send(h.data, zmq::send_flags::dontwait);
            }
            ++passed;
            held.pop_front();
        }
    }
    std::cerr << "loss_proxy: passed " << passed << ", dropped " << dropped << "\n";
    return 0;
}
