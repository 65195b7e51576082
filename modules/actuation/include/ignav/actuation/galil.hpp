// A driver for Galil DMC motion controllers (the paper's controller) over TCP, speaking the
// DMC ASCII command set: commands end with a carriage return; the controller answers ':' when it
// accepts one and '?' when it does not (then `TC1` says why). Axes A, B, C are motors 1-3.
#pragma once

#include <string>

#include "ignav/actuation/controller.hpp"

namespace ignav::actuation {

struct GalilOptions {
  std::string host = "127.0.0.1";
  int port = 23;
  int timeout_ms = 1000;        // per command
  double speed_steps_s = 2000;  // SP, AC, DC sent on connect
  double acceleration_steps_s2 = 8000;
};

class GalilController final : public MotorController {
 public:
  explicit GalilController(GalilOptions options);
  ~GalilController() override;
  GalilController(const GalilController&) = delete;
  GalilController& operator=(const GalilController&) = delete;

  Status connect() override;
  Status home() override;                         // DP 0,0,0: the present position becomes zero
  Status move(const Steps& increments) override;  // PR a,b,c then BG ABC
  Status stop() override;                         // ST ABC
  Status abort() override;                        // AB
  Expected<ControllerStatus> poll() override;     // TP, MG _BGn, MG _SCn
  Status clearFault() override;

  // One command; the reply's data without the trailing ':' (e.g. " 100, 0, -5").
  Expected<std::string> command(const std::string& text);

 private:
  Status ensureConnected();
  GalilOptions options_;
  int fd_ = -1;
  std::string fault_;
  bool limit_cleared_ = false;
};

}  // namespace ignav::actuation
