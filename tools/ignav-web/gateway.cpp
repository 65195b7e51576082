#include "gateway.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast.hpp>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <shared_mutex>
#include <thread>

#include "browser_messages.hpp"
#include "ignav/commands/command_table.hpp"
#include "ignav/protocol/client.hpp"
#include "static_files.hpp"

namespace ignav::web {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

constexpr const char* kVersion = "0.1.0";
// A browser may have this many requests waiting for the server; more is answered "busy".
constexpr int kMaxInFlight = 64;
// A browser that does not read its socket is dropped once this much waits for it (it reconnects
// and gets the whole state again), so that a stalled tab cannot grow the gateway without end.
constexpr std::size_t kMaxOutboxBytes = 32u << 20;
constexpr std::size_t kMaxHttpRequestBytes = 64u << 10;
// How often the gateway looks whether the server is (still) there; a browser hears of a change
// this much later at most (a restarted gateway's pages wait for it before asking for slices).
constexpr auto kServerCheckPeriod = std::chrono::milliseconds(100);
// The server publishes Health once a second. Silent this long, it is gone even while DDS still
// lists it as matched: a killed server's endpoints stay matched until its lease runs out (10 s
// by default), and one whose loop is stuck answers nothing either.
constexpr auto kServerSilence = std::chrono::seconds(3);

class WsSession;

// A browser request on its way to a DDS thread.
struct Job {
  std::weak_ptr<WsSession> from;
  BrowserRequest request;
};

// The requests one DDS thread answers, in order (an emergency stop first).
struct JobQueue {
  std::mutex mutex;
  std::condition_variable ready;
  std::deque<Job> jobs;
};

// How often the state thread drains the state topics when nothing arrives: what a browser sees
// (an emergency stop's phase among it) is at most this late on top of DDS.
constexpr auto kStatePollPeriod = std::chrono::milliseconds(2);

}  // namespace

struct Gateway::Impl {
  GatewayOptions options;
  asio::io_context io;
  tcp::acceptor acceptor{io};
  protocol::Client client;
  std::string subject;                 // of the identity's certificate, "" without security
  std::vector<std::string> permitted;  // what this identity may publish (hello)

  // ---- the I/O thread's ----
  std::set<std::shared_ptr<WsSession>> sessions;
  json full_state = json::object();  // every topic as last sent, for browsers that join later
  bool server_matched = false;

  // ---- between the threads ----
  // Three DDS threads, so that nothing waits behind a slow answer (issue 43: an emergency stop's
  // phase reached pages 0.5-0.8 s late behind slices): "commands" answers commands, approvals and
  // emergency stops; "views" slices and the 3D view's scene; "state" relays the state topics and
  // watches the server. protocol::Client allows the three at once.
  JobQueue commands, views;
  std::atomic<bool> stopping{false};
  // The client's participant: shared by the three, made anew (DDS Security) by the state thread
  // alone, with the other two out of it.
  std::shared_mutex participant;
  // When a Health sample last arrived (steady clock, ns; 0: none yet): the state thread writes
  // it, the request threads read it.
  std::atomic<Clock::rep> last_health_ns{0};

  // ---- the state thread's ----
  bool server_alive = false;  // matched, and not silent (what browsers are told)
  // Unmatched for 5 s under DDS Security: the client's participant is made anew (doubling).
  protocol::RemakeSchedule remake{std::chrono::milliseconds(5000),
                                  std::chrono::milliseconds(60000)};

  Impl(GatewayOptions o)
      : options(std::move(o)),
        client(options.domain, options.dds_config_xml, options.client_id,
               options.identity ? &*options.identity : nullptr, options.robot_id) {
    if (options.identity) {
      std::ifstream pem(options.identity->certificate);
      subject = protocol::certificateSubject(
          std::string(std::istreambuf_iterator<char>(pem), std::istreambuf_iterator<char>()));
    }
    for (const auto& spec : commands::inputTable()) {
      if ((spec.traits & commands::kFromClients) && client.mayPublish(spec.name))
        permitted.push_back(spec.name);
    }
    // Browsers never wait for a reply by polling; the DDS thread sleeps on the waitset.
    client.setReplySpin(std::chrono::microseconds(0));
    boost::system::error_code ec;
    const auto address = asio::ip::make_address(options.listen_address, ec);
    if (ec) throw std::runtime_error("--listen '" + options.listen_address + "': " + ec.message());
    const tcp::endpoint endpoint(address, options.port);
    acceptor.open(endpoint.protocol());
    acceptor.set_option(asio::socket_base::reuse_address(true));
    acceptor.bind(endpoint, ec);
    if (ec) {
      throw std::runtime_error("cannot listen on " + options.listen_address + ":" +
                               std::to_string(options.port) + ": " + ec.message());
    }
    acceptor.listen();
  }

  void accept();
  void serveHttp(tcp::socket socket);

  // I/O thread.
  void joined(const std::shared_ptr<WsSession>& s);
  void left(const std::shared_ptr<WsSession>& s);
  void fromBrowser(const std::shared_ptr<WsSession>& s, std::string_view text);
  void broadcast(const json& message);

  // DDS threads.
  void stateLoop();
  void requestLoop(JobQueue& queue);
  bool serverSilent() const;
  std::optional<Clock::time_point> lastHealth() const;
  json answer(const BrowserRequest& request);
  // From a DDS thread to a browser (or all), on the I/O thread.
  void post(std::weak_ptr<WsSession> to, json message, bool completes_request);
};

namespace {

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket socket, Gateway::Impl& gateway)
      : ws_(std::move(socket)), gateway_(gateway) {}

  void start(http::request<http::string_body> upgrade) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(kMaxMessageBytes);
    peer_ = endpointName();
    ws_.async_accept(upgrade, [self = shared_from_this()](beast::error_code ec) {
      if (ec)
        return spdlog::warn("browser {}: WebSocket handshake failed: {}", self->peer_,
                            ec.message());
      self->gateway_.joined(self);
      self->read();
    });
  }

  void send(const json& message) {
    if (closed_) return;
    auto text = std::make_shared<const std::string>(message.dump());
    outbox_bytes_ += text->size();
    outbox_.push_back(std::move(text));
    if (outbox_bytes_ > kMaxOutboxBytes) {
      spdlog::warn("browser {}: {} MiB unread, dropped (it will reconnect)", peer_,
                   outbox_bytes_ >> 20);
      return close();
    }
    if (outbox_.size() == 1) write();
  }

  int in_flight = 0;
  const std::string& peer() const { return peer_; }

 private:
  std::string endpointName() {
    beast::error_code ec;
    const auto remote = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
    return ec ? std::string("?")
              : remote.address().to_string() + ":" + std::to_string(remote.port());
  }

  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->close();
      const std::string text = beast::buffers_to_string(self->buffer_.data());
      self->buffer_.consume(self->buffer_.size());
      self->gateway_.fromBrowser(self, text);
      self->read();
    });
  }

  void write() {
    ws_.text(true);
    ws_.async_write(asio::buffer(*outbox_.front()),
                    [self = shared_from_this()](beast::error_code ec, std::size_t) {
                      if (ec) return self->close();
                      self->outbox_bytes_ -= self->outbox_.front()->size();
                      self->outbox_.pop_front();
                      if (!self->outbox_.empty()) self->write();
                    });
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().close(ignored);
    gateway_.left(shared_from_this());
  }

  websocket::stream<beast::tcp_stream> ws_;
  Gateway::Impl& gateway_;
  beast::flat_buffer buffer_;
  std::deque<std::shared_ptr<const std::string>> outbox_;
  std::size_t outbox_bytes_ = 0;
  bool closed_ = false;
  std::string peer_;
};

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, Gateway::Impl& gateway)
      : stream_(std::move(socket)), gateway_(gateway) {}

  void read() {
    parser_.emplace();
    parser_->body_limit(kMaxHttpRequestBytes);
    stream_.expires_after(std::chrono::seconds(30));
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) {
                       if (ec) return self->shutdown();
                       self->handle(self->parser_->release());
                     });
  }

 private:
  void handle(http::request<http::string_body> req) {
    if (websocket::is_upgrade(req)) {
      if (req.target() != "/ws") return respond(req, http::status::not_found, "no WebSocket here");
      if (!sameOrigin(req)) {
        return respond(req, http::status::forbidden,
                       "a page from another origin may not drive the robot");
      }
      stream_.expires_never();
      std::make_shared<WsSession>(stream_.release_socket(), gateway_)->start(std::move(req));
      return;
    }
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      return respond(req, http::status::method_not_allowed, "only GET");
    }
    if (req.target() == "/healthz") {
      const json health = {{"ok", true},
                           {"server", gateway_.server_matched},
                           {"browsers", gateway_.sessions.size()}};
      return respond(req, http::status::ok, health.dump(), "application/json");
    }
    const auto file = staticFile(gateway_.options.app_dir,
                                 std::string_view(req.target().data(), req.target().size()));
    if (!file) return respond(req, http::status::bad_request, "not a plain file name");
    std::ifstream in(*file, std::ios::binary);
    if (!in) return respond(req, http::status::not_found, "no such file");
    std::string body((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    respond(req, http::status::ok, std::move(body), contentType(*file));
  }

  // Browsers send Origin on every WebSocket handshake: one from another site's page (which a
  // user might have open beside ours) must not reach the robot through the user's loopback.
  static bool sameOrigin(const http::request<http::string_body>& req) {
    const auto origin = req.find(http::field::origin);
    if (origin == req.end()) return true;  // not a browser
    const auto host = req.find(http::field::host);
    return host != req.end() && (origin->value() == "http://" + std::string(host->value()) ||
                                 origin->value() == "https://" + std::string(host->value()));
  }

  void respond(const http::request<http::string_body>& req, http::status status, std::string body,
               const std::string& type = "text/plain; charset=utf-8") {
    auto res = std::make_shared<http::response<http::string_body>>(status, req.version());
    res->set(http::field::server, std::string("ignav-web/") + kVersion);
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, "no-cache");
    res->keep_alive(req.keep_alive());
    const bool head = req.method() == http::verb::head;
    res->body() = std::move(body);
    res->prepare_payload();
    if (head) res->body().clear();
    http::async_write(stream_, *res,
                      [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
                        if (ec || !res->keep_alive()) return self->shutdown();
                        self->read();
                      });
  }

  void shutdown() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
  }

  beast::tcp_stream stream_;
  Gateway::Impl& gateway_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

}  // namespace

void Gateway::Impl::accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec) {
      if (ec != asio::error::operation_aborted) spdlog::warn("accept: {}", ec.message());
      if (!acceptor.is_open()) return;
    } else {
      // Small messages both ways: without this, Nagle's algorithm meeting the browser's delayed
      // ACK holds a reply that follows another message for 40 ms (bench_web measured it).
      beast::error_code ignored;
      socket.set_option(tcp::no_delay(true), ignored);
      std::make_shared<HttpSession>(std::move(socket), *this)->read();
    }
    accept();
  });
}

void Gateway::Impl::joined(const std::shared_ptr<WsSession>& s) {
  sessions.insert(s);
  spdlog::info("browser {} connected ({} in all)", s->peer(), sessions.size());
  s->send(helloMessage(options.client_id, options.robot_id, subject, options.identity.has_value(),
                       kVersion, permitted));
  s->send(stateMessage(full_state, {}));
  s->send(connectionMessage(server_matched));
}

void Gateway::Impl::left(const std::shared_ptr<WsSession>& s) {
  if (sessions.erase(s) > 0) {
    spdlog::info("browser {} disconnected ({} left)", s->peer(), sessions.size());
  }
}

void Gateway::Impl::fromBrowser(const std::shared_ptr<WsSession>& s, std::string_view text) {
  auto parsed = parseBrowserMessage(text);
  if (auto* bad = std::get_if<BadRequest>(&parsed)) {
    spdlog::warn("browser {}: bad request: {}", s->peer(), bad->message);
    return s->send(errorMessage(bad->seq, "bad_request", bad->message));
  }
  auto& request = std::get<BrowserRequest>(parsed);
  const bool emergency = std::holds_alternative<EmergencyStopRequest>(request.body);
  // An emergency stop is never refused for being one too many.
  if (!emergency && s->in_flight >= kMaxInFlight) {
    return s->send(errorMessage(
        request.seq, "busy",
        "more than " + std::to_string(kMaxInFlight) + " requests are waiting for the server"));
  }
  ++s->in_flight;
  const bool view = std::holds_alternative<SliceRequest>(request.body) ||
                    std::holds_alternative<SceneRequest>(request.body);
  JobQueue& queue = view ? views : commands;
  {
    std::lock_guard lock(queue.mutex);
    // An emergency stop goes ahead of everything queued.
    if (emergency) {
      queue.jobs.push_front({s, std::move(request)});
    } else {
      queue.jobs.push_back({s, std::move(request)});
    }
  }
  queue.ready.notify_one();
}

void Gateway::Impl::broadcast(const json& message) {
  for (const auto& s : sessions)
    s->send(message);
}

void Gateway::Impl::post(std::weak_ptr<WsSession> to, json message, bool completes_request) {
  asio::post(io, [this, to = std::move(to), message = std::move(message), completes_request] {
    if (to.expired() && !completes_request) {  // a state change: for everyone
      if (message.value("type", "") == "state") full_state.update(message["state"]);
      if (message.value("type", "") == "connection") server_matched = message["server"];
      return broadcast(message);
    }
    if (const auto s = to.lock()) {
      if (completes_request) --s->in_flight;
      s->send(message);
    }
  });
}

json Gateway::Impl::answer(const BrowserRequest& request) {
  const std::uint64_t seq = request.seq;
  const bool emergency = std::holds_alternative<EmergencyStopRequest>(request.body);
  // An emergency stop is sent even when the server seems absent: discovery may be catching up.
  if (!emergency && !client.waitForServer(std::chrono::milliseconds(1))) {
    return errorMessage(
        seq, "no_server",
        "no ignav-server is matched on DDS domain " + std::to_string(options.domain));
  }
  if (!emergency && serverSilent()) {
    const auto silent_s =
        std::chrono::duration_cast<std::chrono::seconds>(Clock::now() - *lastHealth()).count();
    return errorMessage(seq, "no_server",
                        "ignav-server on DDS domain " + std::to_string(options.domain) +
                            " has published nothing for " + std::to_string(silent_s) +
                            " s (its health comes once a second)");
  }
  const auto timeout = options.reply_timeout;
  try {
    if (const auto* c = std::get_if<CommandRequest>(&request.body)) {
      return replyMessage(seq, client.send(c->kind, c->args, timeout));
    }
    if (const auto* a = std::get_if<ApproveRequest>(&request.body)) {
      return replyMessage(seq, client.approve(a->plan_id, a->digest, timeout));
    }
    if (emergency) return replyMessage(seq, client.emergencyStop(timeout));
    if (const auto* scene = std::get_if<SceneRequest>(&request.body)) {
      return sceneMessage(
          seq, client.scene(scene->part, scene->first_slice, scene->max_voxels_per_axis, timeout));
    }
    return sliceMessage(seq, client.slice(std::get<SliceRequest>(request.body).args, timeout));
  } catch (const protocol::Timeout& e) {
    return errorMessage(seq, "timeout", std::string("the server did not answer: ") + e.what());
  } catch (const protocol::PermissionDenied& e) {
    return errorMessage(seq, "not_permitted", e.what());
  } catch (const std::exception& e) {
    return errorMessage(seq, "failed", e.what());
  }
}

// Heard from once, and not since kServerSilence. (Before its first Health sample a matched server
// counts as there: its state follows the match at once.)
std::optional<Clock::time_point> Gateway::Impl::lastHealth() const {
  const Clock::rep ns = last_health_ns.load();
  if (ns == 0) return std::nullopt;
  return Clock::time_point(Clock::duration(ns));
}

bool Gateway::Impl::serverSilent() const {
  const auto last = lastHealth();
  return last && Clock::now() - *last > kServerSilence;
}

void Gateway::Impl::requestLoop(JobQueue& queue) {
  while (!stopping) {
    std::optional<Job> job;
    {
      std::unique_lock lock(queue.mutex);
      queue.ready.wait(lock, [&] { return stopping || !queue.jobs.empty(); });
      if (stopping) return;
      job = std::move(queue.jobs.front());
      queue.jobs.pop_front();
    }
    json message;
    {
      std::shared_lock lock(participant);
      message = answer(job->request);
    }
    post(job->from, std::move(message), true);
  }
}

void Gateway::Impl::stateLoop() {
  auto next_check = Clock::now();
  while (!stopping) {
    std::vector<std::string> changed;
    {
      std::shared_lock lock(participant);
      changed = client.poll();
      if (!changed.empty()) post({}, stateMessage(client.state(), changed), false);
      for (const auto& outcome : client.takeJobOutcomes())
        post({}, jobOutcomeMessage(outcome), false);
    }
    const bool heard = std::find(changed.begin(), changed.end(), "health") != changed.end();
    if (heard) last_health_ns = Clock::now().time_since_epoch().count();
    // At once when a silent server speaks again, else every check period.
    if (Clock::now() >= next_check || (heard && !server_alive)) {
      next_check = Clock::now() + kServerCheckPeriod;
      bool matched = false;
      {
        std::shared_lock lock(participant);
        matched = client.waitForServer(std::chrono::milliseconds(1));
      }
      // With DDS Security, a handshake that lost a message never ends (Cyclone 0.10): a client
      // unmatched for a while is made anew, waiting twice as long each time (up to a minute).
      if (matched) {
        remake.matched();
      } else if (options.identity && remake.due()) {
        spdlog::warn("ignav-server unmatched for {} s: making the DDS participant anew",
                     std::chrono::duration_cast<std::chrono::seconds>(remake.attempt()).count());
        std::unique_lock lock(participant);
        client.makeParticipantAnew();
        remake.remade();
      }
      const bool silent = serverSilent();
      if ((matched && !silent) != server_alive) {
        server_alive = matched && !silent;
        spdlog::info("ignav-server {} on DDS domain {}",
                     server_alive ? "matched"
                     : matched    ? "lost (matched, but no health for 3 s)"
                                  : "lost (unmatched)",
                     options.domain);
        post({}, connectionMessage(server_alive), false);
      }
    }
    if (changed.empty()) std::this_thread::sleep_for(kStatePollPeriod);
  }
}

Gateway::Gateway(GatewayOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

Gateway::~Gateway() {
  stop();
}

std::uint16_t Gateway::port() const {
  return impl_->acceptor.local_endpoint().port();
}

namespace {

void wakeRequestThreads(Gateway::Impl& impl) {
  for (JobQueue* queue : {&impl.commands, &impl.views}) {
    std::lock_guard lock(queue->mutex);  // a thread between its check and its wait hears it
    queue->ready.notify_all();
  }
}

}  // namespace

void Gateway::run() {
  std::thread state([this] { impl_->stateLoop(); });
  std::thread commands([this] { impl_->requestLoop(impl_->commands); });
  std::thread views([this] { impl_->requestLoop(impl_->views); });
  impl_->accept();
  impl_->io.run();
  impl_->stopping = true;
  wakeRequestThreads(*impl_);
  state.join();
  commands.join();
  views.join();
}

void Gateway::stop() {
  impl_->stopping = true;
  wakeRequestThreads(*impl_);
  asio::post(impl_->io, [impl = impl_.get()] {
    beast::error_code ignored;
    impl->acceptor.close(ignored);
    impl->io.stop();
  });
}

}  // namespace ignav::web
