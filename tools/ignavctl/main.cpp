// ignavctl: a human and scripted client of ignav-server over DDS.
//   ignavctl status | load PATH|phantom | fiducials auto | fiducials set P1 P2 P3
//   ignavctl targets add X,Y,Z | rm ID | ls | clear | lock | unlock | pause MM|none ID
//   ignavctl slice --view axial --lps X,Y,Z --out s.png | watch | run script.yaml
//   ignavctl approval | approve [--yes] [--plan N --digest HEX] | motion | emergency-stop
//   ignavctl verify [load PATH [same-frame] | place ID X,Y,Z | accept ID | reject SEED | fit NAME
//                    | aim NAME | discard NAME | scan PATH [same-frame] | reaim]
//   ignavctl replay SESSION [--speed 1|10|max] [--until SEQ]
//   ignavctl robots (the servers on the domain); --robot ID picks one where several share it
//   ignavctl doctor (participants, robots, round trips, clock offsets, what looks wrong)
//   and every other command by its name: ignavctl ping | add-target X,Y,Z | check-ready robot ...
// ignavctl's own options (--json, --domain, --robot, ...) go before or after the subcommand.
// This file builds the command line and runs what it chose; subcommands.hpp lists the groups.
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <iostream>

#include "subcommands.hpp"

namespace {

using ignav::ctl::GlobalOptions;

void addGlobalOptions(CLI::App& app, GlobalOptions& o) {
  app.add_option("--domain", o.domain, "DDS domain id");
  app.add_option("--dds-config", o.dds_config,
                 "Cyclone XML, or a name: loopback, site-multicast, site-unicast ('' = Cyclone's "
                 "defaults)");
  app.add_option("--dds-interface", o.dds_site.interface,
                 "the network interface a site configuration uses");
  // One value each time: after the subcommand, `--dds-peer HOST` must not take its arguments.
  app.add_option("--dds-peer", o.dds_site.peers, "a unicast discovery peer, once per host")
      ->allow_extra_args(false);
  app.add_option("--client-id", o.client_id, "who this client is in replies and the journal");
  app.add_flag("--json", o.as_json, "machine-readable output");
  app.add_option("--wait-server", o.wait_s, "seconds to wait for the server");
  app.add_option("--robot", o.robot_id,
                 "the robot whose server to talk to (its robot_id); needed when several robots "
                 "share the domain")
      ->envname("IGNAV_ROBOT");
  app.add_option("--identity", o.identity,
                 "DDS Security identity folder (cert.pem, key.pem, permissions.p7s, ...); "
                 "without one, security is off")
      ->envname("IGNAV_IDENTITY");
}

}  // namespace

int main(int argc, char** argv) {
  using namespace ignav::ctl;
  CLI::App app{"ignavctl: drive ignav-server over DDS"};
  app.require_subcommand(1);
  // A subcommand hands the options it does not know to the main app, so that ignavctl's own
  // stand where people type them: `ignavctl status --json` as `ignavctl --json status`. The
  // subcommands inherit both settings when added, so they come first.
  app.fallthrough();
  app.footer(
      "ignavctl's own options (--json, --domain, --robot, --identity, ...: ignavctl "
      "--help) go before or after the subcommand.");
  GlobalOptions options;
  options.client_id = "ignavctl-" + std::to_string(::getpid());
  addGlobalOptions(app, options);

  Action chosen;
  try {
    addDomainCommands(app, chosen);
    addStateViews(app, chosen);
    addAliasCommands(app, chosen);
    addScriptRunner(app, chosen);
    addMotionCommands(app, chosen);
    addVerify(app, chosen);
    addReplay(app, chosen);
    addCommandsByName(app, chosen);
    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      return app.exit(e);
    }
    if (chosen.run_alone) return chosen.run_alone(options);
    const Domain domain = openDomain(options);
    if (chosen.on_domain) return chosen.on_domain(domain);
    return withServer(domain, chosen.on_server);
  } catch (const UsageError& e) {
    std::cerr << "ignavctl: " << e.what() << "\n";
    return kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "ignavctl: " << e.what() << "\n";
    return kExitRejected;
  }
}
