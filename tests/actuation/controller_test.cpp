// The simulated controller against closed-form trapezoids, and the Galil DMC driver against the
// dmc-emulator process on loopback.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "ignav/actuation/controller.hpp"
#include "ignav/actuation/galil.hpp"
#include "support/dmc_emulator.hpp"

namespace ignav::actuation {
namespace {

using test::Emulator;

using namespace std::chrono_literals;

SimulatedController connected(std::array<SimulatedAxis, 3> axes = {}) {
  SimulatedController c(axes);
  EXPECT_TRUE(c.connect().ok());
  return c;
}

TEST(SimulatedController, ArrivesWhenTheTrapezoidSaysSo) {
  auto c = connected();  // 2000 steps/s, 8000 steps/s²
  ASSERT_TRUE(c.move({{4000, -100, 0}}).ok());
  c.advanceTo(0.1);
  EXPECT_EQ(c.poll()->position.motor[0], 40);  // ½·8000·0.1²
  c.advanceTo(2.2);
  EXPECT_EQ(c.poll()->state, ControllerState::kMoving);  // 4000/2000 + 2000/8000 = 2.25 s
  EXPECT_FALSE(c.move({{1, 1, 1}}).ok());                // not while moving
  c.advanceTo(2.25);
  const auto s = c.poll().value();
  EXPECT_EQ(s.state, ControllerState::kIdle);
  EXPECT_EQ(s.position.motor, (std::array<std::int64_t, 3>{4000, -100, 0}));
  EXPECT_EQ(c.movesStarted(), 1u);
}

TEST(SimulatedController, StopDeceleratesAbortHalts) {
  auto c = connected();
  ASSERT_TRUE(c.move({{4000, 0, 0}}).ok());
  c.advanceTo(1.0);  // cruising at 2000 steps/s, at 1750 steps
  ASSERT_TRUE(c.stop().ok());
  c.advanceTo(2.0);
  auto s = c.poll().value();
  EXPECT_EQ(s.state, ControllerState::kIdle);
  // 2000²/(2·8000) = 250 more steps to rest.
  EXPECT_EQ(s.position.motor[0], 1750 + 250);
  ASSERT_TRUE(c.move({{-1000, 0, 0}}).ok());
  c.advanceTo(2.2);
  ASSERT_TRUE(c.abort().ok());
  const auto at_abort = c.poll()->position.motor[0];
  c.advanceTo(5.0);
  EXPECT_EQ(c.poll()->position.motor[0], at_abort);
  EXPECT_EQ(c.poll()->state, ControllerState::kIdle);
}

TEST(SimulatedController, LimitSwitchStallAndMismatchFaults) {
  std::array<SimulatedAxis, 3> axes{};
  axes[1].max_steps = 1000;
  auto c = connected(axes);
  ASSERT_TRUE(c.move({{0, 5000, 0}}).ok());
  c.advanceTo(10.0);
  auto s = c.poll().value();
  EXPECT_EQ(s.state, ControllerState::kFault);
  EXPECT_EQ(s.position.motor[1], 1000);
  EXPECT_NE(s.fault.find("motor 2 hit its limit switch at 1000 steps"), std::string::npos);
  EXPECT_FALSE(c.move({{1, 0, 0}}).ok());  // no motion in a fault
  ASSERT_TRUE(c.clearFault().ok());
  ASSERT_TRUE(c.move({{0, -1000, 0}}).ok());
  c.advanceTo(20.0);
  EXPECT_EQ(c.poll()->state, ControllerState::kIdle);

  c.inject(InjectedFault::kStall, 0);
  ASSERT_TRUE(c.move({{3000, 0, 0}}).ok());
  c.advanceTo(30.0);
  s = c.poll().value();
  EXPECT_EQ(s.position.motor[0], 1500);
  EXPECT_NE(s.fault.find("motor 1 stalled at 1500 steps"), std::string::npos);
  ASSERT_TRUE(c.clearFault().ok());

  c.inject(InjectedFault::kPositionMismatch, 2);
  ASSERT_TRUE(c.move({{0, 0, 100}}).ok());
  c.advanceTo(40.0);
  EXPECT_EQ(c.poll()->position.motor[2], 107);  // commanded 100: the server must notice

  c.inject(InjectedFault::kLostConnection);
  const auto lost = c.poll();
  ASSERT_FALSE(lost.ok());
  EXPECT_EQ(lost.error().reason, "connection_lost");
  EXPECT_TRUE(c.connect().ok());
  EXPECT_TRUE(c.poll().ok());
}

// ---- the Galil driver against dmc-emulator --------------------------------------------------

// Ten times the default speed, so the tests' moves take a fraction of a second.
GalilOptions fastAxes(int port) {
  GalilOptions o;
  o.port = port;
  o.speed_steps_s = 20000;
  o.acceleration_steps_s2 = 200000;
  return o;
}

ControllerStatus waitIdle(GalilController& g) {
  const auto end = std::chrono::steady_clock::now() + 10s;
  for (;;) {
    auto s = g.poll();
    EXPECT_TRUE(s.ok()) << s.error().message;
    if (!s.ok() || s->state != ControllerState::kMoving || std::chrono::steady_clock::now() > end) {
      return s.ok() ? *s : ControllerStatus{};
    }
    std::this_thread::sleep_for(10ms);
  }
}

TEST(GalilController, MovesStopsAndReportsRefusalsOverTcp) {
  Emulator emu;
  GalilController g(fastAxes(emu.port()));
  ASSERT_TRUE(g.connect().ok());
  ASSERT_TRUE(g.home().ok());
  ASSERT_TRUE(g.move({{4000, -2000, 1000}}).ok());
  auto s = waitIdle(g);
  EXPECT_EQ(s.state, ControllerState::kIdle);
  EXPECT_EQ(s.position.motor, (std::array<std::int64_t, 3>{4000, -2000, 1000}));

  // A long move, stopped: it comes to rest short of its goal.
  ASSERT_TRUE(g.move({{200000, 0, 0}}).ok());
  std::this_thread::sleep_for(100ms);
  ASSERT_TRUE(g.stop().ok());
  s = waitIdle(g);
  EXPECT_GT(s.position.motor[0], 4000);
  EXPECT_LT(s.position.motor[0], 4000 + 200000);

  const auto refused = g.command("XQ #nothing");
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("Unrecognized command"), std::string::npos)
      << refused.error().message;

  emu.kill();
  const auto lost = g.poll();
  ASSERT_FALSE(lost.ok());
  EXPECT_EQ(lost.error().reason, "connection_lost");
}

TEST(GalilController, LimitSwitchBecomesAFault) {
  Emulator emu("--limit-max 1000");
  GalilController g(fastAxes(emu.port()));
  ASSERT_TRUE(g.connect().ok());
  ASSERT_TRUE(g.move({{5000, 0, 0}}).ok());
  const auto s = waitIdle(g);
  EXPECT_EQ(s.state, ControllerState::kFault);
  EXPECT_NE(s.fault.find("forward limit switch at 1000 steps"), std::string::npos) << s.fault;
  EXPECT_FALSE(g.move({{1, 0, 0}}).ok());
}

}  // namespace
}  // namespace ignav::actuation
