#include "ignav/protocol/wire/dds.hpp"

#include "ignav/protocol/config.hpp"
#include "ignav/protocol/security.hpp"
#include "ignav/protocol/wire/security.hpp"

#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

namespace ignav::protocol {
namespace {

dds_qos_t* makeQos(Qos kind) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  if (kind == Qos::kState || kind == Qos::kStateOfMany) {
    dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, kind == Qos::kState ? 1 : 64);
  } else {
    dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 64);
  }
  return q;
}

struct QosHolder {
  explicit QosHolder(Qos kind) : qos(makeQos(kind)) {}
  ~QosHolder() { dds_delete_qos(qos); }
  QosHolder(const QosHolder&) = delete;
  QosHolder& operator=(const QosHolder&) = delete;
  dds_qos_t* qos;
};

// A topic's QoS is one per participant: a reader of many writers keeps more history, its topic
// is the state topic every other entity of the participant uses.
dds_entity_t makeTopic(const Participant& p, const dds_topic_descriptor_t* desc, const char* name,
                       Qos kind) {
  const QosHolder qos(kind == Qos::kStateOfMany ? Qos::kState : kind);
  return check(dds_create_topic(p.handle(), desc, name, qos.qos, nullptr), name);
}

std::size_t matchedOf(dds_entity_t entity, bool writer) {
  if (writer) {
    dds_publication_matched_status_t s{};
    check(dds_get_publication_matched_status(entity, &s), "publication_matched");
    return s.current_count;
  }
  dds_subscription_matched_status_t s{};
  check(dds_get_subscription_matched_status(entity, &s), "subscription_matched");
  return s.current_count;
}

// Cyclone 0.10 authenticates one identity per process and domain: a second participant with
// another certificate is created but never matches anyone (found by the security e2e tests).
// The identities in use, so that this is an error instead of silence.
// The domain entity a configuration made is the process's, not one participant's: it goes with the
// last participant on it (a participant made anew beside others must not take their domain along).
struct DomainIdentity {
  std::string certificate;  // "" = security off
  int participants = 0;
  dds_entity_t domain = 0;  // made by dds_create_domain for these participants; 0 = none
};
std::mutex g_identities_mutex;
std::map<std::uint32_t, DomainIdentity> g_identities;

void claimIdentity(std::uint32_t domain, const std::string& certificate) {
  std::lock_guard<std::mutex> lock(g_identities_mutex);
  auto& d = g_identities[domain];
  if (d.participants > 0 && d.certificate != certificate) {
    throw DdsError("DDS domain " + std::to_string(domain) + ": this process already has a " +
                   (d.certificate.empty() ? std::string("participant without security")
                                          : "participant with the identity " + d.certificate) +
                   "; Cyclone DDS authenticates one identity per process and domain (use one "
                   "process per identity)");
  }
  d.certificate = certificate;
  ++d.participants;
}

void adoptDomain(std::uint32_t domain, dds_entity_t entity) {
  std::lock_guard<std::mutex> lock(g_identities_mutex);
  g_identities[domain].domain = entity;
}

void releaseIdentity(std::uint32_t domain) {
  std::lock_guard<std::mutex> lock(g_identities_mutex);
  auto it = g_identities.find(domain);
  if (it != g_identities.end() && --it->second.participants <= 0) {
    if (it->second.domain > 0) dds_delete(it->second.domain);
    g_identities.erase(it);
  }
}

}  // namespace

dds_return_t check(dds_return_t rc, const char* what) {
  if (rc == DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) {
    throw PermissionDenied(std::string(what) +
                           ": not allowed by DDS Security (this identity's permissions)");
  }
  if (rc < 0) throw DdsError(std::string(what) + ": " + dds_strretcode(rc));
  return rc;
}

Participant::Participant(std::uint32_t domain_id, const std::string& config_xml,
                         const SecurityIdentity* identity, const std::string& robot_id,
                         const std::string& name)
    : domain_id_(domain_id) {
  if (robot_id != kAnyRobot) {
    if (const std::string problem = robotIdProblem(robot_id); !problem.empty()) {
      throw DdsError("robot id '" + robot_id + "' " + problem);
    }
  }
  claimIdentity(domain_id, identity ? identity->certificate : "");
  try {
    create(domain_id, config_xml, identity, robot_id, name);
  } catch (...) {
    // No destructor runs: what create() made goes here.
    if (participant_ > 0) dds_delete(participant_);
    releaseIdentity(domain_id);
    throw;
  }
}

void Participant::create(std::uint32_t domain_id, const std::string& config_xml,
                         const SecurityIdentity* identity, const std::string& robot_id,
                         const std::string& name) {
  if (!config_xml.empty()) {
    const dds_entity_t domain = dds_create_domain(domain_id, config_xml.c_str());
    if (domain < 0 && domain != DDS_RETCODE_PRECONDITION_NOT_MET) {
      // PRECONDITION_NOT_MET: this process already created the domain (tests with two
      // participants); the existing configuration is used.
      check(domain, "dds_create_domain");
    }
    if (domain > 0) adoptDomain(domain_id, domain);
  }
  dds_qos_t* qos = dds_create_qos();
  if (!name.empty()) dds_qset_entity_name(qos, name.c_str());
  if (identity) {
    try {
      addSecurityQos(qos, *identity);
    } catch (...) {
      dds_delete_qos(qos);
      throw;
    }
  }
  participant_ = dds_create_participant(domain_id, qos, nullptr);
  dds_delete_qos(qos);
  if (participant_ < 0 && identity) {
    throw DdsError("DDS Security refused the identity in " + identity->folder +
                   " (its certificate, key, permissions or governance is invalid, expired or "
                   "not signed by its CA; Cyclone's log names which): " +
                   dds_strretcode(participant_));
  }
  check(participant_, "participant");
  secure_ = identity != nullptr;
  dds_qos_t* scope = dds_create_qos();
  const std::string partition = robotPartition(robot_id);
  const char* partitions[] = {partition.c_str()};
  dds_qset_partition(scope, 1, partitions);
  publisher_ = dds_create_publisher(participant_, scope, nullptr);
  subscriber_ = dds_create_subscriber(participant_, scope, nullptr);
  dds_delete_qos(scope);
  check(publisher_ < 0 ? publisher_ : subscriber_, "publisher/subscriber of the robot partition");
}

Participant::~Participant() {
  dds_delete(participant_);
  releaseIdentity(domain_id_);
}

template <typename T>
Writer<T>::Writer(const Participant& p, const dds_topic_descriptor_t* desc, const char* name,
                  Qos qos) {
  const QosHolder q(qos);
  const dds_entity_t t = makeTopic(p, desc, name, qos);
  writer_ = check(dds_create_writer(p.publisher(), t, q.qos, nullptr), name);
}

template <typename T>
std::size_t Writer<T>::matched() const {
  return matchedOf(writer_, true);
}

template <typename T>
Reader<T>::Reader(const Participant& p, const dds_topic_descriptor_t* desc, const char* name,
                  Qos qos) {
  const QosHolder q(qos);
  const dds_entity_t t = makeTopic(p, desc, name, qos);
  reader_ = check(dds_create_reader(p.subscriber(), t, q.qos, nullptr), name);
}

template <typename T>
Reader<T>::Reader(const Participant& p, const dds_topic_descriptor_t* desc, const char* name,
                  Qos qos, dds_topic_filter_arg_fn keep, void* arg) {
  const QosHolder q(qos);
  // A topic entity of this reader's own: Cyclone applies a filter to every reader of the entity,
  // and it must be set before any data can flow.
  const dds_entity_t t = makeTopic(p, desc, name, qos);
  dds_set_topic_filter_and_arg(t, keep, arg);
  reader_ = check(dds_create_reader(p.subscriber(), t, q.qos, nullptr), name);
}

template <typename T>
std::size_t Reader<T>::matched() const {
  return matchedOf(reader_, false);
}

template <typename T>
std::size_t Reader<T>::takeWithState(const std::function<void(const T&, bool)>& fn) const {
  constexpr int kBatch = 32;
  std::size_t count = 0;
  for (;;) {
    void* samples[kBatch] = {};
    dds_sample_info_t infos[kBatch];
    const dds_return_t n = dds_take(reader_, samples, infos, kBatch, kBatch);
    if (n <= 0) break;
    for (int i = 0; i < n; ++i) {
      // Only a disposal says an instance is gone (its last data, if not yet taken, comes with
      // it); data whose writer has left since (a sender that exited at once) is still data.
      if (infos[i].instance_state == DDS_IST_NOT_ALIVE_DISPOSED) {
        fn(*static_cast<const T*>(samples[i]), false);
        ++count;
      } else if (infos[i].valid_data) {
        fn(*static_cast<const T*>(samples[i]), true);
        ++count;
      }
    }
    dds_return_loan(reader_, samples, n);
    if (n < kBatch) break;
  }
  return count;
}

template <typename T>
std::size_t Reader<T>::takeFrom(
    const std::function<void(const T&, dds_instance_handle_t)>& fn) const {
  constexpr int kBatch = 32;
  std::size_t count = 0;
  for (;;) {
    void* samples[kBatch] = {};
    dds_sample_info_t infos[kBatch];
    const dds_return_t n = dds_take(reader_, samples, infos, kBatch, kBatch);
    if (n <= 0) break;
    for (int i = 0; i < n; ++i) {
      // Not the instance state: a command whose sender has already gone (an emergency stop from
      // a script that exits at once) is still a command (docs/RELIABILITY.md, R2).
      if (!infos[i].valid_data) continue;
      fn(*static_cast<const T*>(samples[i]), infos[i].publication_handle);
      ++count;
    }
    dds_return_loan(reader_, samples, n);
    if (n < kBatch) break;
  }
  return count;
}

template <typename T>
std::size_t Reader<T>::take(const std::function<void(const T&)>& fn) const {
  return takeWithState([&](const T& s, bool alive) {
    if (alive) fn(s);
  });
}

WaitSet::WaitSet(const Participant& p) {
  waitset_ = check(dds_create_waitset(p.handle()), "waitset");
  guard_ = check(dds_create_guardcondition(p.handle()), "guardcondition");
  check(dds_waitset_attach(waitset_, guard_, guard_), "attach guard");
}

void WaitSet::attach(dds_entity_t reader) {
  const dds_entity_t cond = check(dds_create_readcondition(reader, DDS_ANY_STATE), "readcondition");
  conditions_.push_back(cond);
  check(dds_waitset_attach(waitset_, cond, reader), "attach reader");
}

void WaitSet::trigger() {
  dds_set_guardcondition(guard_, true);
}

bool WaitSet::wait(std::chrono::milliseconds timeout) {
  dds_attach_t triggered[16];
  const dds_return_t n = dds_waitset_wait(waitset_, triggered, 16, DDS_MSECS(timeout.count()));
  bool fired = false;
  dds_take_guardcondition(guard_, &fired);
  return n > 0 || fired;
}

// The protocol's types.
template class Writer<ignav_msg_Command>;
template class Reader<ignav_msg_Command>;
template class Writer<ignav_msg_Reply>;
template class Reader<ignav_msg_Reply>;
template class Writer<ignav_msg_SliceRequest>;
template class Reader<ignav_msg_SliceRequest>;
template class Writer<ignav_msg_SliceReply>;
template class Reader<ignav_msg_SliceReply>;
template class Writer<ignav_msg_SceneRequest>;
template class Reader<ignav_msg_SceneRequest>;
template class Writer<ignav_msg_SceneReply>;
template class Reader<ignav_msg_SceneReply>;
template class Writer<ignav_msg_WorkflowState>;
template class Reader<ignav_msg_WorkflowState>;
template class Writer<ignav_msg_RobotState>;
template class Reader<ignav_msg_RobotState>;
template class Writer<ignav_msg_VolumeState>;
template class Reader<ignav_msg_VolumeState>;
template class Writer<ignav_msg_RegistrationState>;
template class Reader<ignav_msg_RegistrationState>;
template class Writer<ignav_msg_TargetState>;
template class Reader<ignav_msg_TargetState>;
template class Writer<ignav_msg_Health>;
template class Reader<ignav_msg_Health>;
template class Writer<ignav_msg_JobOutcome>;
template class Reader<ignav_msg_JobOutcome>;
template class Writer<ignav_msg_Approval>;
template class Reader<ignav_msg_Approval>;
template class Writer<ignav_msg_EmergencyStop>;
template class Reader<ignav_msg_EmergencyStop>;
template class Writer<ignav_msg_ApprovalState>;
template class Reader<ignav_msg_ApprovalState>;
template class Writer<ignav_msg_MotionState>;
template class Reader<ignav_msg_MotionState>;
template class Writer<ignav_msg_VerificationState>;
template class Writer<ignav_msg_StructuresState>;
template class Reader<ignav_msg_StructuresState>;
template class Reader<ignav_msg_VerificationState>;

}  // namespace ignav::protocol
