// The DDS configuration a participant starts from (configs/dds/*.xml, docs/DEPLOYMENT.md).
#pragma once

#include <string>
#include <vector>

namespace ignav::protocol {

// Reads a Cyclone configuration file's text; throws DdsError (errors.hpp) naming the file.
std::string readConfigFile(const std::string& path);

// What the shipped site configurations leave to the site: they hold ${IGNAV_DDS_INTERFACE} and a
// <Peer address="${IGNAV_DDS_PEERS}"/> line, which loadDdsConfig fills in.
struct DdsSite {
  std::string interface;           // a network interface of this host (server.yaml dds.interface)
  std::vector<std::string> peers;  // unicast discovery peers: addresses or host names (dds.peers)
};

// Whether `value` names a configuration ("loopback", "site-multicast", "site-unicast") rather than
// a file: no '/' and no ".xml".
bool isDdsConfigName(const std::string& value);
// The file a configuration name or path stands for: a path as it is; a name as <dir>/<name>.xml
// in the first of `dirs` that has it (throws DdsError listing where it looked).
std::string resolveDdsConfig(const std::string& value, const std::vector<std::string>& dirs);
// Where tools look for a configuration name: $IGNAV_DDS_CONFIGS, the source tree's configs/dds
// (a build tree's tools), /etc/ignav/dds (the Debian package).
std::vector<std::string> ddsConfigDirs();
// Reads `path` and fills in the site's settings. Throws DdsError naming the file and the setting:
// a placeholder the site left empty, an interface this host does not have (listing those it has),
// a peer that is not an address or host name.
std::string loadDdsConfig(const std::string& path, const DdsSite& site);
// What a tool's --dds-config VALUE gives: "" for "" (Cyclone's defaults), else the file or the
// name found in ddsConfigDirs(), loaded with `site`.
std::string loadToolDdsConfig(const std::string& value, const DdsSite& site);

// Whether a thread waiting for a DDS sample should poll for a while before sleeping: only when
// this process may run on more than one CPU. Waking a sleeping thread on another, idle core costs
// ~150 µs on a VM, so polling pays there; confined to one CPU (taskset, cpusets), polling only
// takes that CPU from the DDS receive thread that has to deliver the sample (docs/PERFORMANCE.md).
bool pollingPaysOff();

}  // namespace ignav::protocol
