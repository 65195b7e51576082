// DDS Security (docs/SECURITY.md): the identity a participant presents. Authentication (X.509),
// access control (signed governance and permissions) and AES-GCM encryption are Cyclone's own
// plugins; this only hands them the files and reads back the result. The participant QoS it
// needs and who sent a sample: wire/security.hpp.
#pragma once

#include <string>

namespace ignav::protocol {

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

// What is wrong with an identity, checked as Cyclone's plugins will check it, before anything is
// created: the certificate and key parse and belong together, the certificate is issued by the
// identity CA and valid now, governance and permissions are signed by the permissions CA, and the
// plugins are there. "" when nothing is; else the file and what is wrong with it.
std::string identityProblem(const SecurityIdentity& identity);

// Where Debian's Cyclone keeps its security plugins (found when ignav was configured).
std::string defaultSecurityPluginDir();

// The subject (RFC 2253, "CN=approver,O=ignav,C=NL") of the certificate in `pem`.
std::string certificateSubject(const std::string& pem);

}  // namespace ignav::protocol
