// A synchronous WebSocket client that speaks to ignav-web as a browser tab does (docs/WEB.md):
// for the gateway's tests and its benchmark, not for the gateway itself.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include <boost/asio.hpp>
#include <boost/beast.hpp>
#include <nlohmann/json.hpp>

namespace ignav::web {

class BrowserSocket {
 public:
  // origin: the Origin header a browser would send ("" = none).
  explicit BrowserSocket(std::uint16_t port, const std::string& origin = "") {
    namespace http = boost::beast::http;
    boost::asio::ip::tcp::resolver resolver(io_);
    boost::beast::get_lowest_layer(ws_).connect(
        *resolver.resolve("127.0.0.1", std::to_string(port)));
    // As browsers do: no Nagle delay on small messages.
    boost::beast::get_lowest_layer(ws_).socket().set_option(boost::asio::ip::tcp::no_delay(true));
    ws_.set_option(boost::beast::websocket::stream_base::decorator(
        [origin](boost::beast::websocket::request_type& req) {
          if (!origin.empty()) req.set(http::field::origin, origin);
        }));
    ws_.handshake("127.0.0.1:" + std::to_string(port), "/ws");
  }

  void sendText(const std::string& text) { ws_.write(boost::asio::buffer(text)); }

  // The next message; the state it carries is merged into state(). Throws on timeout.
  nlohmann::json next(std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    boost::beast::get_lowest_layer(ws_).expires_after(timeout);
    boost::beast::flat_buffer buffer;
    ws_.read(buffer);
    last_bytes_ = buffer.size();
    nlohmann::json m = nlohmann::json::parse(boost::beast::buffers_to_string(buffer.data()));
    if (m["type"] == "state") state_.update(m["state"]);
    if (m["type"] == "job_outcome") outcomes_[m["job"].get<std::uint64_t>()] = m;
    return m;
  }

  // Reads until the outcome of background job `job` (a reply's "job") has come.
  nlohmann::json jobOutcome(std::uint64_t job) {
    while (outcomes_.count(job) == 0)
      next();
    return outcomes_.at(job);
  }

  // Reads until a message of `type` (and `seq`, when given).
  nlohmann::json until(const std::string& type, std::optional<std::uint64_t> seq = std::nullopt) {
    for (;;) {
      nlohmann::json m = next();
      if (m["type"] == type && (!seq || m["seq"] == *seq)) return m;
    }
  }

  // Sends `message` with the next seq and returns its answer (reply, slice or error).
  nlohmann::json request(nlohmann::json message) {
    const std::uint64_t seq = ++seq_;
    message["seq"] = seq;
    sendText(message.dump());
    for (;;) {
      nlohmann::json m = next();
      const bool answer = m["type"] == "reply" || m["type"] == "slice" || m["type"] == "error";
      if (answer && m["seq"] == seq) return m;
    }
  }

  void waitState(const std::function<bool(const nlohmann::json&)>& done) {
    while (!done(state_))
      next();
  }

  const nlohmann::json& state() const { return state_; }
  std::size_t lastMessageBytes() const { return last_bytes_; }

 private:
  boost::asio::io_context io_;
  boost::beast::websocket::stream<boost::beast::tcp_stream> ws_{io_};
  nlohmann::json state_ = nlohmann::json::object();
  std::map<std::uint64_t, nlohmann::json> outcomes_;  // job_outcome messages by job
  std::uint64_t seq_ = 0;
  std::size_t last_bytes_ = 0;
};

}  // namespace ignav::web
