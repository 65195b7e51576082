// The DDS configurations a site chooses by name (configs/dds/, docs/DEPLOYMENT.md): names found
// where tools look, the site's interface and peers filled in and checked, and Cyclone's own
// parser taking what comes out (a participant on it). Domain 189.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "ignav/protocol/config.hpp"
#include "ignav/protocol/errors.hpp"
#include "ignav/protocol/wire/dds.hpp"

namespace ignav::protocol {
namespace {

namespace fs = std::filesystem;
const std::string kDir = IGNAV_SOURCE_DIR "/configs/dds";

// The message of what `fn` throws (DdsError), "" if it does not throw.
template <typename Fn>
std::string errorOf(Fn fn) {
  try {
    fn();
  } catch (const DdsError& e) {
    return e.what();
  }
  return "";
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1))
    ++n;
  return n;
}

TEST(DdsConfig, ANameIsAFileWhereToolsLookAndAPathIsItself) {
  EXPECT_TRUE(isDdsConfigName("site-multicast"));
  EXPECT_FALSE(isDdsConfigName("configs/dds/loopback.xml"));
  EXPECT_FALSE(isDdsConfigName("mine.xml"));
  EXPECT_FALSE(isDdsConfigName(""));
  EXPECT_EQ(resolveDdsConfig("loopback", {"/nonexistent", kDir}), kDir + "/loopback.xml");
  EXPECT_EQ(resolveDdsConfig("some/where.xml", {kDir}), "some/where.xml");
  const auto missing = errorOf([] { resolveDdsConfig("site-mullticast", {"/etc/nowhere", kDir}); });
  EXPECT_NE(missing.find("'site-mullticast': no site-mullticast.xml in /etc/nowhere, " + kDir),
            std::string::npos)
      << missing;
  // From the build tree, the tools find the source tree's configurations.
  bool found = false;
  for (const auto& d : ddsConfigDirs())
    found = found || fs::exists(fs::path(d) / "site-unicast.xml");
  EXPECT_TRUE(found);
}

TEST(DdsConfig, TheSiteInterfaceIsFilledInAndOneThisHostLacksIsNamed) {
  const std::string multicast = kDir + "/site-multicast.xml";
  const auto none = errorOf([&] { loadDdsConfig(multicast, {}); });
  EXPECT_NE(none.find("needs the network interface: set dds.interface"), std::string::npos) << none;
  EXPECT_NE(none.find("this host has: "), std::string::npos) << none;
  EXPECT_NE(none.find("lo"), std::string::npos) << none;
  const auto wrong = errorOf([&] { loadDdsConfig(multicast, {"ens99x", {}}); });
  EXPECT_NE(wrong.find(multicast + ": dds.interface: 'ens99x' is not a network interface of "
                                   "this host (it has: "),
            std::string::npos)
      << wrong;
  const std::string xml = loadDdsConfig(multicast, {"lo", {}});
  EXPECT_NE(xml.find("<NetworkInterface name=\"lo\" multicast=\"true\"/>"), std::string::npos);
  EXPECT_EQ(xml.find("${"), std::string::npos);
  // A site's own file naming an interface that is not there: named too.
  const fs::path own = fs::temp_directory_path() / "ignav_own_dds.xml";
  std::ofstream(own) << "<CycloneDDS><Domain><General><Interfaces><NetworkInterface "
                        "name=\"eth9z\"/></Interfaces></General></Domain></CycloneDDS>\n";
  const auto theirs = errorOf([&] { loadDdsConfig(own.string(), {"lo", {}}); });
  EXPECT_NE(theirs.find("NetworkInterface name: 'eth9z' is not a network interface"),
            std::string::npos)
      << theirs;
  std::ofstream(own)
      << "<CycloneDDS><Domain><General><Interfaces><NetworkInterface "
         "name=\"${IGNAV_DDS_NIC}\"/></Interfaces></General></Domain></CycloneDDS>\n";
  const auto unknown = errorOf([&] { loadDdsConfig(own.string(), {"lo", {}}); });
  EXPECT_NE(unknown.find("${IGNAV_DDS_NIC} is not a setting ignav fills in"), std::string::npos)
      << unknown;
  fs::remove(own);
}

TEST(DdsConfig, UnicastPeersBecomeOnePeerEachAndCycloneTakesTheResult) {
  const std::string unicast = kDir + "/site-unicast.xml";
  const auto none = errorOf([&] { loadDdsConfig(unicast, {"lo", {}}); });
  EXPECT_NE(none.find("needs its unicast peers: set dds.peers"), std::string::npos) << none;
  const auto bad = errorOf([&] { loadDdsConfig(unicast, {"lo", {"127.0.0.1", "robot pc"}}); });
  EXPECT_NE(bad.find("dds.peers: 'robot pc' is not an address or host name"), std::string::npos)
      << bad;
  const std::string xml = loadDdsConfig(unicast, {"lo", {"127.0.0.1", "localhost"}});
  EXPECT_EQ(count(xml, "<Peer address="), 2u);
  EXPECT_NE(xml.find("<Peer address=\"127.0.0.1\"/>"), std::string::npos);
  EXPECT_NE(xml.find("<Peer address=\"localhost\"/>"), std::string::npos);
  EXPECT_EQ(xml.find("${"), std::string::npos);
  // Cyclone's parser is the judge of the XML: a participant starts on it (nothing leaves lo).
  EXPECT_NO_THROW(
      Participant(189, loadDdsConfig(unicast, {"lo", {"127.0.0.1"}}), nullptr, "robot-1"));
  // The loopback configuration names no placeholder: read as it is.
  EXPECT_EQ(loadDdsConfig(kDir + "/loopback.xml", {}), readConfigFile(kDir + "/loopback.xml"));
}

}  // namespace
}  // namespace ignav::protocol
