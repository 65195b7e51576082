// The controller component (server/controller_component.hpp) on its own: the Galil driver behind
// a proxy that holds every reply 900 ms (tests/support/delay_proxy.hpp), and the simulation. A
// halt goes out while a poll waits for its reply, drops the moves queued behind it, readings say
// which commands they come after, and a lost connection is reported and then made again.
#include <gtest/gtest.h>

#include <thread>

#include "controller_component.hpp"
#include "ignav/actuation/galil.hpp"
#include "support/approved_moves.hpp"
#include "support/delay_proxy.hpp"
#include "support/dmc_emulator.hpp"

namespace ignav::server {
namespace {

using actuation::ControllerState;
using Clock = std::chrono::steady_clock;
using test::approvedMoves;
using test::released;
using workflow::ControllerAction;
using workflow::ControllerCommand;
using namespace std::chrono_literals;

double ms(Clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

std::unique_ptr<actuation::MotorController> galil(int port) {
  actuation::GalilOptions o;
  o.port = port;
  o.timeout_ms = 1000;
  o.speed_steps_s = 2000;  // slow: a 20000-step move takes 10 s
  o.acceleration_steps_s2 = 20000;
  return std::make_unique<actuation::GalilController>(o);
}

// Waits for an event that satisfies `ok` (false on timeout).
template <typename F>
bool waitEvent(ControllerComponent& c, F ok, std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  while (Clock::now() < end) {
    for (const auto& e : c.take()) {
      if (ok(e)) return true;
    }
    std::this_thread::sleep_for(5ms);
  }
  return false;
}

std::size_t count(const test::DelayProxy& proxy, const std::string& prefix) {
  std::size_t n = 0;
  for (const auto& c : proxy.commands())
    n += c.text.rfind(prefix, 0) == 0;
  return n;
}

TEST(ControllerComponent, AMoveIsReleasedOnlyFromItsApprovalAndStartsWhereTheApprovalSays) {
  const actuation::Steps from{{100, -20, 5}};
  const auto moves = approvedMoves({{{1000, 0, 0}}, {{0, -300, 40}}, {{-7, 0, 0}}}, from);
  ASSERT_EQ(moves.size(), 3u);
  EXPECT_EQ(moves[0].startsAt(), from);
  EXPECT_EQ(moves[1].startsAt(), (actuation::Steps{{1100, -20, 5}}));
  EXPECT_EQ(moves[2].startsAt(), (actuation::Steps{{1100, -320, 45}}));
  EXPECT_EQ(moves[2].increments(), (actuation::Steps{{-7, 0, 0}}));
  for (const auto& m : moves) {
    EXPECT_EQ(m.action(), ControllerAction::kMove);
    EXPECT_EQ(m.digest().size(), 64u);  // SHA-256, hex
    EXPECT_EQ(m.digest(), moves[0].digest());
  }
  // Nothing else carries increments.
  EXPECT_EQ(released(ControllerCommand::home()).increments(), actuation::Steps{});
  EXPECT_TRUE(released(ControllerCommand::abort()).isHalt());
}

TEST(ControllerComponent, AnAbortGoesOutWhileAPollWaitsForASlowReply) {
  test::Emulator dmc;
  test::DelayProxy proxy(dmc.port());
  ControllerComponent c(galil(proxy.port()), {}, {});
  c.start();
  ASSERT_TRUE(c.waitForFirstReading(5s));
  ASSERT_EQ(c.latest().status.state, ControllerState::kIdle) << c.latest().status.fault;
  EXPECT_EQ(c.lifecycle(), Lifecycle::kActive);
  const auto start = Clock::now();
  c.submit(approvedMoves({{{20000, 0, 0}}}).at(0));
  ASSERT_TRUE(proxy.waitFor("BG", start, 5s));
  constexpr auto kSlowReply = 900ms;
  proxy.setDelay(kSlowReply);
  std::this_thread::sleep_for(400ms);  // a poll now waits for its replies
  const auto sent = Clock::now();
  c.submit(released(ControllerCommand::abort()));
  const auto ab = proxy.waitFor("AB", sent, 3s);
  ASSERT_TRUE(ab);
  // Before the proxy let the reply to the poll's command in flight through (kSlowReply after that
  // command reached it): an abort that waited behind the poll comes after it, on any machine.
  Clock::time_point in_flight{};
  for (const auto& cmd : proxy.commands()) {
    if (cmd.at < sent) in_flight = cmd.at;
  }
  EXPECT_LT(ms(*ab - in_flight), ms(kSlowReply))
      << "the abort waited behind the poll (AB " << ms(*ab - sent) << " ms after it was submitted)";
  // The driver waits 900 ms for AB's reply, within its timeout: no failure.
  std::this_thread::sleep_for(1200ms);
  for (const auto& e : c.take())
    EXPECT_NE(e.kind, ControllerEvent::Kind::kCommandFailed) << e.why;
  proxy.setDelay(0ms);
}

TEST(ControllerComponent, AHaltDropsTheMovesQueuedBehindItAndHaltsTheOneOnItsWay) {
  test::Emulator dmc;
  test::DelayProxy proxy(dmc.port());
  ControllerComponent c(galil(proxy.port()), {}, {});
  c.start();
  ASSERT_TRUE(c.waitForFirstReading(5s));
  proxy.setDelay(300ms);
  const auto queued = Clock::now();
  const auto moves = approvedMoves({{{20000, 0, 0}}, {{0, 20000, 0}}});
  c.submit(moves.at(0));
  c.submit(moves.at(1));
  // The first is on its way (PR waits 300 ms for its reply, then BG goes): halt now.
  ASSERT_TRUE(proxy.waitFor("PR 20000", queued, 5s));
  c.submit(released(ControllerCommand::abort()));
  std::this_thread::sleep_for(2500ms);
  // The second move never went; the first never began (the driver saw the halt before BG), and
  // the component halted again after it, in case BG had gone first.
  EXPECT_EQ(count(proxy, "PR 0,20000"), 0u);
  std::vector<std::string> order;
  for (const auto& cmd : proxy.commands()) {
    if (cmd.at >= queued && (cmd.text == "BG ABC" || cmd.text == "AB")) order.push_back(cmd.text);
  }
  EXPECT_EQ(order, (std::vector<std::string>{"AB", "AB"}));
  for (const auto& e : c.take())
    EXPECT_NE(e.kind, ControllerEvent::Kind::kCommandFailed) << e.why;
  proxy.setDelay(0ms);
  EXPECT_EQ(c.latest().status.state, ControllerState::kIdle);
  EXPECT_EQ(c.latest().status.position.motor, (std::array<std::int64_t, 3>{0, 0, 0}));
}

TEST(ControllerComponent, AReadingSaysWhichCommandsCameBeforeIt) {
  std::array<actuation::SimulatedAxis, 3> axes{};
  for (auto& a : axes)
    a.speed_steps_s = a.acceleration_steps_s2 = 40000;
  ControllerComponent c(std::make_unique<actuation::SimulatedController>(axes), {}, {});
  c.start();
  ASSERT_TRUE(c.waitForFirstReading(1s));
  const auto seq = c.submit(approvedMoves({{{1000, -500, 250}}}).at(0));
  EXPECT_LT(c.latest().after_command, seq + 1);
  ASSERT_TRUE(waitEvent(
      c,
      [&](const ControllerEvent& e) {
        if (e.kind != ControllerEvent::Kind::kReading || e.reading.after_command < seq ||
            e.reading.status.state != ControllerState::kIdle) {
          return false;
        }
        EXPECT_EQ(e.reading.status.position.motor, (std::array<std::int64_t, 3>{1000, -500, 250}));
        return true;
      },
      5s));
  // A move that expects the robot elsewhere is not sent, and says why.
  const auto refused = c.submit(approvedMoves({{{1, 0, 0}}}, actuation::Steps{{0, 0, 0}}).at(0));
  ASSERT_TRUE(waitEvent(
      c,
      [&](const ControllerEvent& e) {
        return e.kind == ControllerEvent::Kind::kCommandFailed && e.command == refused &&
               e.why.find("not at 0 / 0 / 0") != std::string::npos;
      },
      2s));
  EXPECT_EQ(c.latest().status.position.motor, (std::array<std::int64_t, 3>{1000, -500, 250}));
}

TEST(ControllerComponent, ALostConnectionIsReportedOnceAndMadeAgain) {
  test::Emulator dmc;
  test::DelayProxy proxy(dmc.port());
  ControllerComponentOptions o;
  o.reconnect_first = 100ms;
  ControllerComponent c(galil(proxy.port()), o, {});
  c.start();
  ASSERT_TRUE(c.waitForFirstReading(5s));
  (void)c.take();
  proxy.cut();
  ASSERT_TRUE(waitEvent(
      c,
      [](const ControllerEvent& e) {
        return e.kind == ControllerEvent::Kind::kReading &&
               e.reading.status.state == ControllerState::kDisconnected &&
               e.reading.status.fault.find("connection lost") != std::string::npos;
      },
      3s));
  ASSERT_TRUE(waitEvent(
      c,
      [](const ControllerEvent& e) {
        return e.kind == ControllerEvent::Kind::kReading &&
               e.reading.status.state == ControllerState::kIdle;
      },
      5s));
  EXPECT_EQ(c.lifecycle(), Lifecycle::kActive);
  // And it works again.
  EXPECT_GE(count(proxy, "SP "), 2u);
}

TEST(ControllerComponent, ASilentControllerIsAFaultWithinTheTimeout) {
  test::Emulator dmc;
  test::DelayProxy proxy(dmc.port());
  ControllerComponent c(galil(proxy.port()), {}, {});
  c.start();
  ASSERT_TRUE(c.waitForFirstReading(5s));
  (void)c.take();
  proxy.setSilent(true);
  const auto silent = Clock::now();
  ASSERT_TRUE(waitEvent(
      c,
      [](const ControllerEvent& e) {
        return e.kind == ControllerEvent::Kind::kReading &&
               e.reading.status.state == ControllerState::kDisconnected &&
               e.reading.status.fault.find("did not answer") != std::string::npos &&
               e.reading.lifecycle == Lifecycle::kLost;  // the reading says it, not only a log
      },
      3s));
  // The poll in flight was sent at most one rest period (200 ms) after the silence began.
  EXPECT_LT(ms(Clock::now() - silent), 1000.0 + 200.0 + 300.0);
  EXPECT_NE(c.lifecycle(), Lifecycle::kActive);
  proxy.setSilent(false);
  // Reconnected by itself: an event in the active lifecycle, with a reading of the robot.
  EXPECT_TRUE(waitEvent(
      c,
      [](const ControllerEvent& e) {
        return e.kind == ControllerEvent::Kind::kReading &&
               e.reading.lifecycle == Lifecycle::kActive &&
               e.reading.status.state != ControllerState::kDisconnected;
      },
      10s));
}

}  // namespace
}  // namespace ignav::server
