// Finding who is on a domain without a server to talk to: the robots' servers (their Health, in
// every robot's partition), every participant, and the robot a tool should talk to.
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>
#include <thread>
#include <tuple>

#include "ignav/protocol/client.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "participant_name.hpp"

namespace ignav::protocol {

using Clock = std::chrono::steady_clock;

std::string participantName(const std::string& who) {
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  return std::string(program_invocation_short_name) + " " + who + "@" + host;
}

std::vector<Health> discoverRobots(std::uint32_t domain_id, const std::string& config_xml,
                                   const SecurityIdentity* identity,
                                   std::chrono::milliseconds wait) {
  auto participant = std::make_unique<Participant>(domain_id, config_xml, identity, kAnyRobot,
                                                   participantName("robots"));
  auto health = std::make_unique<TopicReader<Health>>(*participant, Qos::kStateOfMany);
  // By (robot id, session): two servers with one robot id are both listed.
  std::map<std::pair<std::string, std::string>, Health> seen;
  const auto end = Clock::now() + wait;
  auto last_news = Clock::now();
  std::size_t last_matched = 0;
  // With DDS Security, a participant that matched nothing in its attempt may have lost a
  // handshake message: made anew (as Client::waitForServer).
  RemakeSchedule schedule(std::chrono::milliseconds(3000), std::chrono::milliseconds(30000));
  while (Clock::now() < end) {
    if (identity && last_matched == 0 && schedule.due() &&
        end - Clock::now() > std::chrono::milliseconds(1000)) {
      health.reset();
      participant.reset();  // first: its peers forget its handshake
      participant = std::make_unique<Participant>(domain_id, config_xml, identity, kAnyRobot,
                                                  participantName("robots"));
      health = std::make_unique<TopicReader<Health>>(*participant, Qos::kStateOfMany);
      schedule.remade();
    }
    health->take([&](const Health& h) {
      if (seen.insert_or_assign({h.robot_id, h.session_id}, h).second) last_news = Clock::now();
    });
    const std::size_t matched = health->matched();
    if (matched != last_matched) {
      last_matched = matched;
      last_news = Clock::now();
    }
    // Every matched server heard from, and quiet for a while: a further one is unlikely.
    if (matched > 0 && seen.size() >= matched &&
        Clock::now() - last_news > std::chrono::milliseconds(300)) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::vector<Health> robots;
  for (auto& [key, h] : seen)
    robots.push_back(std::move(h));
  std::sort(robots.begin(), robots.end(), [](const Health& a, const Health& b) {
    return std::tie(a.robot_id, a.started_unix_s) < std::tie(b.robot_id, b.started_unix_s);
  });
  return robots;
}

std::vector<ParticipantSeen> discoverParticipants(std::uint32_t domain_id,
                                                  const std::string& config_xml,
                                                  const SecurityIdentity* identity,
                                                  std::chrono::milliseconds wait) {
  const Participant participant(domain_id, config_xml, identity, kAnyRobot,
                                participantName("doctor"));
  const dds_entity_t reader = check(
      dds_create_reader(participant.handle(), DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, nullptr, nullptr),
      "DCPSParticipant reader");
  dds_guid_t own{};
  check(dds_get_guid(participant.handle(), &own), "dds_get_guid");
  std::this_thread::sleep_for(wait);
  std::vector<ParticipantSeen> seen;
  constexpr int kBatch = 256;
  std::vector<void*> samples(kBatch, nullptr);
  std::vector<dds_sample_info_t> infos(kBatch);
  const dds_return_t n = dds_read(reader, samples.data(), infos.data(), kBatch, kBatch);
  for (int i = 0; i < n; ++i) {
    if (!infos[i].valid_data || infos[i].instance_state != DDS_IST_ALIVE) continue;
    const auto* p = static_cast<const dds_builtintopic_participant_t*>(samples[i]);
    if (std::memcmp(p->key.v, own.v, 12) == 0) continue;  // the prefix: this participant
    ParticipantSeen s;
    char hex[3];
    for (int b = 0; b < 12; ++b) {
      std::snprintf(hex, sizeof hex, "%02x", p->key.v[b]);
      s.guid += hex;
    }
    char* name = nullptr;
    if (p->qos && dds_qget_entity_name(p->qos, &name) && name) {
      s.name = name;
      dds_free(name);
    }
    void* data = nullptr;
    std::size_t size = 0;
    if (p->qos && dds_qget_userdata(p->qos, &data, &size) && data) {
      s.subject = certificateSubject(std::string(static_cast<const char*>(data), size));
      dds_free(data);
    }
    seen.push_back(std::move(s));
  }
  if (n > 0) dds_return_loan(reader, samples.data(), n);
  std::sort(seen.begin(), seen.end(), [](const ParticipantSeen& a, const ParticipantSeen& b) {
    return std::tie(a.name, a.guid) < std::tie(b.name, b.guid);
  });
  return seen;
}

std::string chooseRobot(std::uint32_t domain_id, const std::string& config_xml,
                        const SecurityIdentity* identity, const std::string& named,
                        std::chrono::milliseconds wait) {
  if (!named.empty()) {
    if (const std::string problem = robotIdProblem(named); !problem.empty()) {
      throw RobotNotChosen("robot id '" + named + "' " + problem);
    }
    return named;
  }
  const auto robots = discoverRobots(domain_id, config_xml, identity, wait);
  const std::string domain = "DDS domain " + std::to_string(domain_id);
  if (robots.empty()) {
    throw RobotNotChosen("no ignav-server found on " + domain +
                         " (is it running, on this domain, with a DDS configuration that reaches "
                         "it?)");
  }
  std::set<std::string> ids;
  std::string listed;
  for (const auto& h : robots) {
    ids.insert(h.robot_id);
    listed += (listed.empty() ? "" : ", ") + h.robot_id + " (on " + h.host + ")";
  }
  if (ids.size() > 1) {
    throw RobotNotChosen(std::to_string(ids.size()) + " robots on " + domain + ": " + listed +
                         "; name the one to talk to (--robot ID)");
  }
  return robots.front().robot_id;
}

}  // namespace ignav::protocol
