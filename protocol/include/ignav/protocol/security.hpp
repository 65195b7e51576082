// DDS Security (docs/SECURITY.md): the identity a participant presents, and who sent a sample.
// Authentication (X.509), access control (signed governance and permissions) and AES-GCM
// encryption are Cyclone's own plugins; this only hands them the files and reads back the result.
#pragma once

#include <dds/dds.h>

#include <map>
#include <string>

namespace ignav::protocol {

class Participant;

// The files of one identity (PEM certificates and key, S/MIME-signed XML documents), as paths.
struct SecurityIdentity {
  std::string folder;  // where they came from, for messages
  std::string identity_ca;
  std::string certificate;
  std::string private_key;
  std::string permissions_ca;
  std::string governance;
  std::string permissions;
  std::string plugin_dir;  // holds libdds_security_{auth,ac,crypto}.so
};

// An identity folder as configs/security/make-test-pki.sh writes one: identity_ca.pem,
// permissions_ca.pem, governance.p7s, cert.pem, key.pem, permissions.p7s. Throws DdsError naming
// the folder and the missing file.
SecurityIdentity identityFromFolder(const std::string& folder);

// Where Debian's Cyclone keeps its security plugins (found when ignav was configured).
std::string defaultSecurityPluginDir();

// The participant QoS properties that turn DDS Security on with `id` (file: URIs, full plugin
// paths), and the certificate as USER_DATA so that receivers can name the sender.
void addSecurityQos(dds_qos_t* qos, const SecurityIdentity& id);

// The subject (RFC 2253, "CN=approver,O=ignav,C=NL") of the certificate in `pem`.
std::string certificateSubject(const std::string& pem);

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
