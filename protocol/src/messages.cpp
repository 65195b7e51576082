#include "ignav/protocol/wire/messages.hpp"

#include <algorithm>

#include "ignav/commands/command_table.hpp"

namespace ignav::protocol {

static_assert(kMaxCommandItemsRead == commands::kMaxTargets + 1,
              "the server reads one item past the most a command may carry");

Command commandOf(const ignav_msg_Command& sample) {
  // A shallow copy whose sequences look shorter: nothing past the limit is copied out.
  ignav_msg_Command capped = sample;
  const auto cap = static_cast<std::uint32_t>(kMaxCommandItemsRead);
  capped.points._length = std::min(capped.points._length, cap);
  capped.ids._length = std::min(capped.ids._length, cap);
  return fromMsg(capped);
}

}  // namespace ignav::protocol
