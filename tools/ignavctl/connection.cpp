// From ignavctl's options to a matched server whose present has arrived.
#include <iostream>

#include "ignavctl.hpp"
#include "printers.hpp"

namespace ignav::ctl {

using namespace std::chrono_literals;

int Server::send(const std::string& command, const protocol::CommandArgs& args) const {
  const auto r = client.send(command, args);
  printReply(r, as_json);
  return r.accepted ? 0 : kExitRejected;
}

std::optional<protocol::JobOutcome> Server::sendAndAwaitJob(const std::string& command,
                                                            const protocol::CommandArgs& args,
                                                            double wait_s,
                                                            protocol::Reply* reply) const {
  const auto r = client.send(command, args);
  if (reply) *reply = r;
  if (!r.accepted || !as_json) printReply(r, as_json);
  if (!r.accepted) return std::nullopt;
  auto outcome = client.waitForJobOutcome(
      r.job, std::chrono::milliseconds(static_cast<std::int64_t>(wait_s * 1000.0)));
  client.waitUntil(
      [&](const protocol::StateMirror& m) {
        return m.workflow && m.workflow->revision >= outcome.revision;
      },
      std::chrono::seconds(5));
  return outcome;
}

int Server::notYetKnown() const {
  std::string missing;
  for (const auto& m : client.missingState())
    missing += (missing.empty() ? "" : ", ") + m;
  std::cerr << "ignavctl: not yet known: the server's " << missing
            << " state did not arrive within 5 s\n";
  return kExitNoServer;
}

Domain openDomain(const GlobalOptions& options) {
  Domain d{options, protocol::loadToolDdsConfig(options.dds_config, options.dds_site), std::nullopt,
           std::chrono::milliseconds(static_cast<long>(options.wait_s * 1000))};
  if (!options.identity.empty()) {
    d.security = protocol::identityFromFolder(options.identity);
  } else {
    std::cerr << "ignavctl: DDS Security is off (no --identity): for local development only\n";
  }
  return d;
}

int withServer(const Domain& domain, const Work& work) {
  const GlobalOptions& o = domain.options;
  std::string robot;
  try {
    robot = protocol::chooseRobot(o.domain, domain.xml, domain.identity(), o.robot_id, domain.wait);
  } catch (const protocol::RobotNotChosen& e) {
    std::cerr << "ignavctl: " << e.what() << "\n";
    return o.robot_id.empty() ? kExitNoServer : kExitUsage;
  }
  protocol::Client client(o.domain, domain.xml, o.client_id, domain.identity(), robot);
  if (!client.waitForServer(domain.wait)) {
    std::cerr << "ignavctl: no ignav-server for robot '" << robot << "' on DDS domain " << o.domain
              << (domain.security ? " that authenticates this identity" : "")
              << (o.robot_id.empty() ? "" : " (ignavctl robots lists those there)") << "\n";
    return kExitNoServer;
  }
  // The state topics are transient-local: a late joiner gets the present, each topic on its
  // own. What is printed from it waits for all of it; what is still missing then is "not yet
  // known", never "none" (issue 38: "no motion is waiting" was said while one was).
  const bool present = client.waitForPresent(5s);
  if (!client.mirror().workflow) throw protocol::Timeout("no WorkflowState within 5 s");
  Server server{client, o.as_json, present};
  return work(server);
}

}  // namespace ignav::ctl
