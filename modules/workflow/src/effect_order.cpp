#include "ignav/workflow/effect_order.hpp"

#include <utility>

namespace ignav::workflow {

bool executeStep(Step& step, EffectSink& sink) {
  const Effects& e = step.effects;
  for (const auto& c : e.controller) {
    if (c.isHalt()) sink.halt(c);
  }
  if (!e.journal.empty() && !sink.journal(e.journal)) {
    sink.unjournaled(e);
    return false;
  }
  sink.commit(std::move(step.session));
  for (const auto& c : e.controller) {
    if (!c.isHalt()) sink.command(c);
  }
  sink.publish(e);
  for (const auto& r : e.replies)
    sink.reply(r);
  sink.finish(e);
  return true;
}

}  // namespace ignav::workflow
