// `status`, `slice` and `watch`: what the server shows, changing nothing.
#include <fstream>
#include <iostream>
#include <memory>
#include <thread>

#include "command_words.hpp"
#include "printers.hpp"
#include "subcommands.hpp"

namespace ignav::ctl {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

int showStatus(Server& s) {
  if (!s.present) return s.notYetKnown();
  if (s.as_json) {
    std::cout << s.client.state().dump(2) << "\n";
  } else {
    printStatus(s.client.mirror());
  }
  return 0;
}

struct SliceOptions {
  std::string view = "axial";
  std::string lps;  // X,Y,Z; empty: the origin
  std::uint32_t size = 512;
  std::string out = "slice.png";
};

// The PNG to a file; its pixel -> LPS mapping printed.
int fetchSlice(Server& s, const SliceOptions& o) {
  protocol::SliceArgs a;
  a.view = o.view;
  if (!o.lps.empty()) a.centre_lps = triple(o.lps);
  a.size_px = o.size;
  const auto r = s.client.slice(a);
  if (!r.ok) {
    std::cerr << "ignavctl: slice: " << r.message << "\n";
    return kExitRejected;
  }
  std::ofstream(o.out, std::ios::binary)
      .write(reinterpret_cast<const char*>(r.png.data()),
             static_cast<std::streamsize>(r.png.size()));
  json m = json::array();
  for (int i = 0; i < 4; ++i) {
    m.push_back(
        {r.pixel_to_lps(i, 0), r.pixel_to_lps(i, 1), r.pixel_to_lps(i, 2), r.pixel_to_lps(i, 3)});
  }
  std::cout << json{{"out", o.out}, {"width", r.width}, {"height", r.height}, {"pixel_to_lps", m}}
                   .dump(s.as_json ? -1 : 2)
            << "\n";
  return 0;
}

// One line per changed topic: its name and its JSON view.
int watchState(Server& s, double seconds) {
  const auto end = std::chrono::steady_clock::now() +
                   std::chrono::milliseconds(static_cast<long>(seconds * 1000));
  while (seconds <= 0 || std::chrono::steady_clock::now() < end) {
    for (const auto& topic : s.client.poll()) {
      const json& state = s.client.state();
      const json v = topic == "target" ? state["targets"] : state.value(topic, json());
      std::cout << topic << " " << v.dump() << "\n" << std::flush;
    }
    std::this_thread::sleep_for(20ms);
  }
  return 0;
}

}  // namespace

void addStateViews(CLI::App& app, Action& chosen) {
  onServer(app.add_subcommand("status", "phase, volume, registration, targets"), chosen,
           showStatus);

  auto slice_options = std::make_shared<SliceOptions>();
  auto* slice = app.add_subcommand("slice", "a slice as PNG, with its pixel -> LPS mapping");
  slice->add_option("--view", slice_options->view);
  slice->add_option("--lps", slice_options->lps, "X,Y,Z centre");
  slice->add_option("--size", slice_options->size);
  slice->add_option("--out", slice_options->out);
  onServer(slice, chosen, [slice_options](Server& s) { return fetchSlice(s, *slice_options); });

  auto watch_s = std::make_shared<double>(0.0);
  auto* watch = app.add_subcommand("watch", "print state changes as they happen");
  watch->add_option("--seconds", *watch_s, "stop after this long (0 = until Ctrl-C)");
  onServer(watch, chosen, [watch_s](Server& s) { return watchState(s, *watch_s); });
}

}  // namespace ignav::ctl
