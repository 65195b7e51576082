// The command decoder and the workflow behind it: a stream of DDS Command and Approval samples
// with fuzzed fields (unknown kinds, NaN/inf/huge coordinates, empty and oversized strings and
// sequences, stale or forged plan ids) goes through ignav::server::toInput and workflow::reduce, as
// the server does, from a session that is registered and planning. Checked on every step:
// exactly one reply per command; a rejection changes nothing; nothing moves unless an approval
// of the pending plan was accepted (DESIGN.md safety invariants 1 and 5).
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "fuzz_session.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "ignav/workflow/reducer.hpp"
#include "requests.hpp"

namespace {

using namespace ignav;
using workflow::Input;
using workflow::InputKind;
using workflow::Session;

// Registered on the phantom's markers, planning: where most commands mean something.
const Session& planningSession() {
  static const Session s = fuzz::planningSession({"op"});
  return s;
}

double fuzzedNumber(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 0:
      return std::numeric_limits<double>::quiet_NaN();
    case 1:
      return std::numeric_limits<double>::infinity();
    case 2:
      return -std::numeric_limits<double>::infinity();
    case 3:
      return std::numeric_limits<double>::max();
    case 4:
      return in.ConsumeFloatingPointInRange<double>(-60.0, 60.0);  // inside the phantom
    default:
      return in.ConsumeFloatingPoint<double>();
  }
}

std::string fuzzedString(FuzzedDataProvider& in) {
  if (in.ConsumeBool()) return std::string(in.ConsumeIntegralInRange<std::size_t>(0, 5000), 'x');
  return in.ConsumeRandomLengthString(300);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  Session session = planningSession();
  double t = 1000.0;
  for (int n = 0; n < 32 && in.remaining_bytes() > 0; ++n) {
    std::optional<Input> input;
    std::string client = in.ConsumeBool() ? "op" : fuzzedString(in);
    if (in.ConsumeIntegralInRange<int>(0, 4) == 0) {
      // An approval: of the pending plan, or forged.
      ignav_msg_Approval a{};
      std::string digest =
          session.pending && in.ConsumeBool() ? session.pending->digest : fuzzedString(in);
      a.client_id = protocol::cstr(client);
      a.request_id = in.ConsumeIntegral<std::uint64_t>();
      a.plan_id = session.pending && in.ConsumeBool() ? session.pending->plan_id
                                                      : in.ConsumeIntegral<std::uint64_t>();
      a.digest = protocol::cstr(digest);
      input = ignav::server::toInput(protocol::fromMsg(a));
    } else {
      ignav_msg_Command c{};
      std::string path = in.ConsumeBool() ? "phantom:" : fuzzedString(in);
      std::vector<ignav_msg_Point3> points(in.ConsumeIntegralInRange<std::size_t>(0, 130));
      for (auto& p : points)
        p = {fuzzedNumber(in), fuzzedNumber(in), fuzzedNumber(in)};
      std::vector<std::uint32_t> ids(in.ConsumeIntegralInRange<std::size_t>(0, 130));
      for (auto& id : ids)
        id = in.ConsumeBool() ? in.ConsumeIntegralInRange<std::uint32_t>(0, 8)
                              : in.ConsumeIntegral<std::uint32_t>();
      c.client_id = protocol::cstr(client);
      c.request_id = in.ConsumeIntegral<std::uint64_t>();
      // Mostly our kinds, sometimes any integer (issue 27: every value gets a reply).
      c.kind = in.ConsumeBool() ? in.ConsumeIntegralInRange<std::int32_t>(
                                      0, static_cast<std::int32_t>(workflow::inputTable().size()))
                                : in.ConsumeIntegral<std::int32_t>();
      c.path = protocol::cstr(path);
      protocol::viewSequence(c.points, points);
      protocol::viewSequence(c.ids, ids);
      input = ignav::server::toInput(protocol::commandOf(c));
    }
    if (!input) continue;  // an unknown kind: the server answers "unknown_command"
    t += in.ConsumeFloatingPointInRange<double>(0.0, 200.0);
    input->time_s = t;
    if (workflow::needsControllerReading(input->kind)) {
      actuation::ControllerStatus idle;
      idle.state = actuation::ControllerState::kIdle;
      idle.position = session.position;
      input->controller = idle;
    }
    const auto step = workflow::reduce(session, *input);
    const auto& e = step.effects;
    if (e.replies.size() != 1) __builtin_trap();  // every command: exactly one reply
    const bool accepted = e.replies.front().accepted;
    if (!accepted && (step.session.revision != session.revision || !e.journal.empty()))
      __builtin_trap();  // a rejection changes nothing
    for (const auto& action : e.controller) {
      if (action.action() == workflow::ControllerAction::kMove &&
          !(accepted && input->kind == InputKind::kApprove))
        __builtin_trap();  // nothing moves without an accepted approval
    }
    session = step.session;
  }
  return 0;
}
