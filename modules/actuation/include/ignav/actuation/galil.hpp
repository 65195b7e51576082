// A driver for Galil DMC motion controllers (the paper's controller) over TCP, speaking the
// DMC ASCII command set: commands end with a carriage return; the controller answers ':' when it
// accepts one and '?' when it does not (then `TC1` says why). Axes A, B, C are motors 1-3.
//
// Two TCP handles (a DMC accepts several): one for setup, moves and polls, and one used only for
// the halts (ST, AB), so that stop() and abort() may be called from another thread while a poll
// waits for its reply, and never queue behind it. Connecting and every reply have a timeout; a
// handle whose reply did not come in time is closed (a late reply would answer the next command)
// and the next call says "not connected" until connect() succeeds again.
#pragma once

#include <atomic>
#include <mutex>
#include <string>

#include "ignav/actuation/controller.hpp"

namespace ignav::actuation {

struct GalilOptions {
  std::string host = "127.0.0.1";
  int port = 23;
  int timeout_ms = 1000;        // per command, and per connection attempt
  double speed_steps_s = 2000;  // SP, AC, DC sent on connect (again before a move if refused)
  double acceleration_steps_s2 = 8000;
};

class GalilController final : public MotorController {
 public:
  explicit GalilController(GalilOptions options);
  ~GalilController() override;
  GalilController(const GalilController&) = delete;
  GalilController& operator=(const GalilController&) = delete;

  Status connect() override;                      // both handles, then SP AC DC SH
  Status home() override;                         // DP 0,0,0: the present position becomes zero
  Status move(const Steps& increments) override;  // PR a,b,c then BG ABC
  Status stop() override;                         // ST ABC, on the halt handle
  Status abort() override;                        // AB, on the halt handle
  Expected<ControllerStatus> poll() override;     // TP, MG _BGn, MG _SCn
  Status clearFault() override;
  bool concurrentHalts() const override { return true; }

  // One command on the main handle; the reply's data without the trailing ':' (" 100, 0, -5").
  Expected<std::string> command(const std::string& text);

 private:
  Expected<int> open() const;  // a connected socket, within the timeout
  Expected<std::string> exchange(int& fd, const std::string& text);
  Status setup();
  Status halt(const std::string& text);

  GalilOptions options_;
  std::mutex main_mutex_;  // fd_, fault_, limit_cleared_, setup_pending_
  int fd_ = -1;
  std::string fault_;
  bool limit_cleared_ = false;
  bool setup_pending_ = false;  // the controller refused the profile (it was moving): again later
  std::mutex halt_mutex_;       // halt_fd_
  int halt_fd_ = -1;
  std::atomic<unsigned> halts_{0};  // halts asked for: a move waiting for PR's reply stops there
};

}  // namespace ignav::actuation
