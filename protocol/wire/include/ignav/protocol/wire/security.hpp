// DDS Security on the wire (docs/SECURITY.md): the participant QoS an identity needs, and who
// published a sample. For protocol/ and the server; tools need only security.hpp.
#pragma once

#include <dds/dds.h>

#include <map>
#include <string>

#include "ignav/protocol/security.hpp"

namespace ignav::protocol {

class Participant;

// The participant QoS properties that turn DDS Security on with `id` (file: URIs, full plugin
// paths), and the certificate as USER_DATA so that receivers can name the sender.
void addSecurityQos(dds_qos_t* qos, const SecurityIdentity& id);

// Who published a sample. With DDS Security on, a participant's GUID is derived from its
// certificate's subject (the "adjusted GUID" of the DDS Security spec, checked by the
// authentication handshake); the certificate the participant carries in USER_DATA is accepted as
// its identity only when it chains to our identity CA and its subject hashes to that GUID.
class SenderIdentities {
 public:
  struct Sender {
    std::string subject;  // "" when not verified
    std::string why_not;  // when not verified
  };
  // identity_ca_pem: the CA file (as in SecurityIdentity::identity_ca).
  SenderIdentities(const Participant& participant, const std::string& identity_ca_pem);
  ~SenderIdentities();
  SenderIdentities(const SenderIdentities&) = delete;
  SenderIdentities& operator=(const SenderIdentities&) = delete;

  // `publication`: dds_sample_info_t::publication_handle of a sample `reader` took.
  Sender of(dds_entity_t reader, dds_instance_handle_t publication);

 private:
  Sender verify(const dds_guid_t& participant_key);
  dds_entity_t participants_ = 0;  // the DCPSParticipant built-in reader
  std::string ca_pem_;
  std::map<std::string, Sender> verified_;  // by participant GUID (bytes)
};

}  // namespace ignav::protocol
