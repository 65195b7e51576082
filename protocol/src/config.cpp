#include "ignav/protocol/config.hpp"

#include <sched.h>

#include <ifaddrs.h>
#include <net/if.h>
#include <netdb.h>
#include <sys/socket.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <set>
#include <sstream>

#include "ignav/protocol/errors.hpp"

namespace ignav::protocol {
namespace {

namespace fs = std::filesystem;

constexpr const char* kInterfacePlaceholder = "${IGNAV_DDS_INTERFACE}";
constexpr const char* kPeersPlaceholder = "${IGNAV_DDS_PEERS}";

std::string interfacesOfThisHost() {
  std::set<std::string> names;
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) == 0) {
    for (const ifaddrs* a = list; a; a = a->ifa_next)
      names.insert(a->ifa_name);
    ::freeifaddrs(list);
  }
  std::string text;
  for (const auto& n : names)
    text += (text.empty() ? "" : ", ") + n;
  return text.empty() ? "none found" : text;
}

// Why an interface of this host cannot carry DDS (down, or no IP address); nothing if it can.
std::optional<std::string> unusableInterface(const std::string& name) {
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return std::nullopt;  // cannot tell: let Cyclone try
  bool up = false, addressed = false;
  for (const ifaddrs* a = list; a; a = a->ifa_next) {
    if (name != a->ifa_name) continue;
    up = up || (a->ifa_flags & IFF_UP) != 0;
    const int family = a->ifa_addr ? a->ifa_addr->sa_family : AF_UNSPEC;
    addressed = addressed || family == AF_INET || family == AF_INET6;
  }
  ::freeifaddrs(list);
  if (!up) return std::string("is down");
  if (!addressed) return std::string("has no IP address");
  return std::nullopt;
}

// Why a peer does not resolve to an address; nothing if it does.
std::optional<std::string> unresolvable(const std::string& peer) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const int rc = ::getaddrinfo(peer.c_str(), nullptr, &hints, &found);
  if (rc != 0) return std::string(::gai_strerror(rc));
  ::freeaddrinfo(found);
  return std::nullopt;
}

void replaceAll(std::string& text, const std::string& what, const std::string& with) {
  for (std::size_t at = text.find(what); at != std::string::npos;
       at = text.find(what, at + with.size())) {
    text.replace(at, what.size(), with);
  }
}

}  // namespace

std::string readConfigFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DdsError(path + ": cannot read the DDS configuration");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

bool isDdsConfigName(const std::string& value) {
  return !value.empty() && value.find('/') == std::string::npos &&
         (value.size() < 4 || value.compare(value.size() - 4, 4, ".xml") != 0);
}

std::string resolveDdsConfig(const std::string& value, const std::vector<std::string>& dirs) {
  if (!isDdsConfigName(value)) return value;
  std::string looked;
  for (const auto& dir : dirs) {
    const fs::path candidate = fs::path(dir) / (value + ".xml");
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec)) return candidate.lexically_normal().string();
    looked += (looked.empty() ? "" : ", ") + dir;
  }
  throw DdsError("DDS configuration '" + value + "': no " + value + ".xml in " +
                 (looked.empty() ? std::string("any folder") : looked) +
                 " (a name is loopback, site-multicast, site-unicast or a site's own; or give a "
                 "path)");
}

std::vector<std::string> ddsConfigDirs() {
  std::vector<std::string> dirs;
  if (const char* env = std::getenv("IGNAV_DDS_CONFIGS"); env && *env) dirs.emplace_back(env);
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  // build/tools/<tool>/<exe> or build/server/<exe>: the source tree is the build's parent.
  if (!ec) dirs.push_back((exe.parent_path() / "../../../configs/dds").lexically_normal().string());
  if (!ec) dirs.push_back((exe.parent_path() / "../../configs/dds").lexically_normal().string());
  dirs.emplace_back("/etc/ignav/dds");
  return dirs;
}

std::string loadDdsConfig(const std::string& path, const DdsSite& site) {
  std::string xml = readConfigFile(path);
  const bool wants_interface = xml.find(kInterfacePlaceholder) != std::string::npos;
  if (wants_interface) {
    if (site.interface.empty()) {
      throw DdsError(path +
                     ": this configuration needs the network interface: set dds.interface "
                     "(server.yaml) or --dds-interface (this host has: " +
                     interfacesOfThisHost() + ")");
    }
    // A name or an address, nothing that would change the XML around it.
    static const std::regex interface_text(R"([A-Za-z0-9._:%@-]{1,64})");
    if (!std::regex_match(site.interface, interface_text)) {
      throw DdsError(path + ": dds.interface: '" + site.interface +
                     "' is not a network interface name or address (this host has: " +
                     interfacesOfThisHost() + ")");
    }
    replaceAll(xml, kInterfacePlaceholder, site.interface);
  }
  const std::size_t marker = xml.find(kPeersPlaceholder);
  if (marker != std::string::npos) {
    if (site.peers.empty()) {
      throw DdsError(path +
                     ": this configuration needs its unicast peers: set dds.peers "
                     "(server.yaml) or --dds-peer once per host");
    }
    static const std::regex plain(R"([A-Za-z0-9.:_-]+)");
    const std::size_t line_start = xml.rfind('\n', marker) + 1;
    const std::size_t line_end = std::min(xml.find('\n', marker), xml.size());
    const std::string line = xml.substr(line_start, line_end - line_start);
    std::string lines;
    for (const auto& peer : site.peers) {
      if (!std::regex_match(peer, plain)) {
        throw DdsError(path + ": dds.peers: '" + peer + "' is not an address or host name");
      }
      // Cyclone drops a peer it cannot resolve and starts anyway: a server that never finds
      // its clients. Said here instead.
      if (auto why = unresolvable(peer)) {
        throw DdsError(path + ": dds.peers: '" + peer + "' does not resolve: " + *why);
      }
      std::string one = line;
      replaceAll(one, kPeersPlaceholder, peer);
      lines += one + "\n";
    }
    xml.replace(line_start, std::min(line_end + 1, xml.size()) - line_start, lines);
  }
  if (const std::size_t left = xml.find("${IGNAV_"); left != std::string::npos) {
    throw DdsError(path + ": " + xml.substr(left, xml.find('}', left) + 1 - left) +
                   " is not a setting ignav fills in");
  }
  // Every interface named, the shipped ones and a site's own: Cyclone's own error says only
  // that the domain could not be created.
  static const std::regex named(R"re(<NetworkInterface[^>]*\bname\s*=\s*"([^"]*)")re");
  for (std::sregex_iterator it(xml.begin(), xml.end(), named), end; it != end; ++it) {
    const std::string name = (*it)[1];
    const std::string setting = wants_interface ? "dds.interface" : "NetworkInterface name";
    if (::if_nametoindex(name.c_str()) == 0) {
      throw DdsError(
          path + ": " + setting + ": '" + name +
          "' is not a network interface of this host (it has: " + interfacesOfThisHost() + ")");
    }
    if (auto why = unusableInterface(name)) {
      throw DdsError(path + ": " + setting + ": '" + name + "' " + *why +
                     " (DDS needs an interface that is up with an IP address)");
    }
  }
  return xml;
}

std::string loadToolDdsConfig(const std::string& value, const DdsSite& site) {
  return value.empty() ? "" : loadDdsConfig(resolveDdsConfig(value, ddsConfigDirs()), site);
}

bool pollingPaysOff() {
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof allowed, &allowed) != 0) return true;
  return CPU_COUNT(&allowed) > 1;
}

}  // namespace ignav::protocol
