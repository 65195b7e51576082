#include "ignav/protocol/wire/security.hpp"

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <openssl/sha.h>
#include <openssl/x509.h>
#include <openssl/x509_vfy.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <vector>

#include "ignav/protocol/wire/dds.hpp"

namespace ignav::protocol {
namespace {

namespace fs = std::filesystem;

template <typename T, void (*Free)(T*)>
struct Deleter {
  void operator()(T* p) const { Free(p); }
};
using X509Ptr = std::unique_ptr<X509, Deleter<X509, X509_free>>;
using StorePtr = std::unique_ptr<X509_STORE, Deleter<X509_STORE, X509_STORE_free>>;
using StoreCtxPtr = std::unique_ptr<X509_STORE_CTX, Deleter<X509_STORE_CTX, X509_STORE_CTX_free>>;
using BioPtr = std::unique_ptr<BIO, Deleter<BIO, BIO_free_all>>;

X509Ptr parsePem(const std::string& pem) {
  BioPtr bio(BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size())));
  if (!bio) return nullptr;
  return X509Ptr(PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr));
}

std::string subjectOf(X509* cert) {
  BioPtr out(BIO_new(BIO_s_mem()));
  X509_NAME_print_ex(out.get(), X509_get_subject_name(cert), 0, XN_FLAG_RFC2253);
  char* data = nullptr;
  const long n = BIO_get_mem_data(out.get(), &data);
  return std::string(data, static_cast<std::size_t>(n));
}

// The first 48 bits of a participant GUID under DDS Security: a set top bit, then the first 47
// bits of SHA-256 over the DER-encoded subject name (DDS Security 1.1, 9.3.3).
bool prefixMatchesSubject(X509* cert, const dds_guid_t& guid) {
  unsigned char* der = nullptr;
  const int size = i2d_X509_NAME(X509_get_subject_name(cert), &der);
  if (size <= 0) return false;
  unsigned char hash[SHA256_DIGEST_LENGTH];
  SHA256(der, static_cast<std::size_t>(size), hash);
  OPENSSL_free(der);
  unsigned char carry = 0x80;
  for (int i = 0; i < 6; ++i) {
    const auto expected = static_cast<unsigned char>(carry | (hash[i] >> 1));
    if (guid.v[i] != expected) return false;
    carry = static_cast<unsigned char>(hash[i] << 7);
  }
  return true;
}

using KeyPtr = std::unique_ptr<EVP_PKEY, Deleter<EVP_PKEY, EVP_PKEY_free>>;
using Pkcs7Ptr = std::unique_ptr<PKCS7, Deleter<PKCS7, PKCS7_free>>;

std::string fileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// OpenSSL's reason for the last failure, and the queue emptied.
std::string opensslReason() {
  const unsigned long code = ERR_get_error();
  ERR_clear_error();
  if (code == 0) return "not valid";
  char text[256];
  ERR_error_string_n(code, text, sizeof text);
  return text;
}

// An S/MIME-signed document verified against the CA that must have signed it.
std::string signedBy(const std::string& path, X509* ca, const char* ca_name) {
  const std::string text = fileText(path);
  BioPtr in(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
  BIO* content = nullptr;
  Pkcs7Ptr p7(in ? SMIME_read_PKCS7(in.get(), &content) : nullptr);
  BioPtr content_owner(content);
  if (!p7) return path + ": not an S/MIME signed document (" + opensslReason() + ")";
  StorePtr store(X509_STORE_new());
  X509_STORE_add_cert(store.get(), ca);
  BioPtr out(BIO_new(BIO_s_mem()));
  if (PKCS7_verify(p7.get(), nullptr, store.get(), content, out.get(), PKCS7_TEXT) != 1) {
    return path + ": its signature does not verify against " + ca_name + " (" + opensslReason() +
           ")";
  }
  return "";
}

std::string fileUri(const std::string& path) {
  return "file:" + fs::absolute(path).lexically_normal().string();
}

}  // namespace

SecurityIdentity identityFromFolder(const std::string& folder) {
  SecurityIdentity id;
  id.folder = folder;
  const fs::path dir(folder);
  auto need = [&](const char* name) {
    const fs::path p = dir / name;
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) {
      throw DdsError("identity folder " + folder + ": " + name +
                     " is missing (expected identity_ca.pem, permissions_ca.pem, governance.p7s, "
                     "cert.pem, key.pem, permissions.p7s; see configs/security/make-test-pki.sh)");
    }
    return p.string();
  };
  id.identity_ca = need("identity_ca.pem");
  id.permissions_ca = need("permissions_ca.pem");
  id.governance = need("governance.p7s");
  id.certificate = need("cert.pem");
  id.private_key = need("key.pem");
  id.permissions = need("permissions.p7s");
  id.plugin_dir = defaultSecurityPluginDir();
  return id;
}

std::string defaultSecurityPluginDir() {
  return IGNAV_DDS_SECURITY_PLUGIN_DIR;
}

void addSecurityQos(dds_qos_t* qos, const SecurityIdentity& id) {
  const std::string dir = id.plugin_dir.empty() ? defaultSecurityPluginDir() : id.plugin_dir;
  auto plugin = [&](const char* name) {
    const fs::path p = fs::path(dir) / name;
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) {
      throw DdsError("DDS Security plugin " + p.string() +
                     " is missing (set security.plugins to the folder holding Cyclone's "
                     "libdds_security_*.so)");
    }
    return p.string();
  };
  dds_qset_prop(qos, "dds.sec.auth.library.path", plugin("libdds_security_auth.so").c_str());
  dds_qset_prop(qos, "dds.sec.auth.library.init", "init_authentication");
  dds_qset_prop(qos, "dds.sec.auth.library.finalize", "finalize_authentication");
  dds_qset_prop(qos, "dds.sec.crypto.library.path", plugin("libdds_security_crypto.so").c_str());
  dds_qset_prop(qos, "dds.sec.crypto.library.init", "init_crypto");
  dds_qset_prop(qos, "dds.sec.crypto.library.finalize", "finalize_crypto");
  dds_qset_prop(qos, "dds.sec.access.library.path", plugin("libdds_security_ac.so").c_str());
  dds_qset_prop(qos, "dds.sec.access.library.init", "init_access_control");
  dds_qset_prop(qos, "dds.sec.access.library.finalize", "finalize_access_control");
  dds_qset_prop(qos, "dds.sec.auth.identity_ca", fileUri(id.identity_ca).c_str());
  dds_qset_prop(qos, "dds.sec.auth.identity_certificate", fileUri(id.certificate).c_str());
  dds_qset_prop(qos, "dds.sec.auth.private_key", fileUri(id.private_key).c_str());
  dds_qset_prop(qos, "dds.sec.access.permissions_ca", fileUri(id.permissions_ca).c_str());
  dds_qset_prop(qos, "dds.sec.access.governance", fileUri(id.governance).c_str());
  dds_qset_prop(qos, "dds.sec.access.permissions", fileUri(id.permissions).c_str());
  const std::string pem = readConfigFile(id.certificate);
  dds_qset_userdata(qos, pem.data(), pem.size());
}

std::string identityProblem(const SecurityIdentity& id) {
  auto cert = parsePem(fileText(id.certificate));
  if (!cert) return id.certificate + ": not a PEM certificate (" + opensslReason() + ")";
  auto identity_ca = parsePem(fileText(id.identity_ca));
  if (!identity_ca) return id.identity_ca + ": not a PEM certificate (" + opensslReason() + ")";
  auto permissions_ca = parsePem(fileText(id.permissions_ca));
  if (!permissions_ca) {
    return id.permissions_ca + ": not a PEM certificate (" + opensslReason() + ")";
  }
  const std::string key_text = fileText(id.private_key);
  BioPtr key_bio(BIO_new_mem_buf(key_text.data(), static_cast<int>(key_text.size())));
  KeyPtr key(key_bio ? PEM_read_bio_PrivateKey(key_bio.get(), nullptr, nullptr, nullptr) : nullptr);
  if (!key) return id.private_key + ": not a PEM private key (" + opensslReason() + ")";
  if (X509_check_private_key(cert.get(), key.get()) != 1) {
    ERR_clear_error();
    return id.private_key + ": not the key of " + id.certificate + " (" + subjectOf(cert.get()) +
           ")";
  }
  StorePtr store(X509_STORE_new());
  StoreCtxPtr ctx(X509_STORE_CTX_new());
  if (!store || !ctx || X509_STORE_add_cert(store.get(), identity_ca.get()) != 1 ||
      X509_STORE_CTX_init(ctx.get(), store.get(), cert.get(), nullptr) != 1) {
    return id.certificate + ": cannot be checked (" + opensslReason() + ")";
  }
  if (X509_verify_cert(ctx.get()) != 1) {
    const int error = X509_STORE_CTX_get_error(ctx.get());
    ERR_clear_error();
    return id.certificate + " (" + subjectOf(cert.get()) + "): not accepted by " + id.identity_ca +
           " (" + subjectOf(identity_ca.get()) + "): " + X509_verify_cert_error_string(error);
  }
  for (const auto* doc : {&id.governance, &id.permissions}) {
    if (auto bad = signedBy(*doc, permissions_ca.get(), id.permissions_ca.c_str()); !bad.empty()) {
      return bad;
    }
  }
  const std::string dir = id.plugin_dir.empty() ? defaultSecurityPluginDir() : id.plugin_dir;
  for (const char* plugin :
       {"libdds_security_auth.so", "libdds_security_ac.so", "libdds_security_crypto.so"}) {
    std::error_code ec;
    if (!fs::is_regular_file(fs::path(dir) / plugin, ec)) {
      return "DDS Security plugin " + (fs::path(dir) / plugin).string() +
             " is missing (set security.plugins to the folder holding Cyclone's "
             "libdds_security_*.so)";
    }
  }
  return "";
}

std::string certificateSubject(const std::string& pem) {
  auto cert = parsePem(pem);
  return cert ? subjectOf(cert.get()) : std::string();
}

SenderIdentities::SenderIdentities(const Participant& participant,
                                   const std::string& identity_ca_pem)
    : ca_pem_(readConfigFile(identity_ca_pem)) {
  participants_ = check(
      dds_create_reader(participant.handle(), DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, nullptr, nullptr),
      "DCPSParticipant reader");
}

SenderIdentities::~SenderIdentities() {
  if (participants_ > 0) dds_delete(participants_);
}

SenderIdentities::Sender SenderIdentities::of(dds_entity_t reader,
                                              dds_instance_handle_t publication) {
  dds_builtintopic_endpoint_t* endpoint = dds_get_matched_publication_data(reader, publication);
  if (!endpoint) return {"", "the publication is not (or no longer) matched"};
  const dds_guid_t key = endpoint->participant_key;
  dds_builtintopic_free_endpoint(endpoint);
  const std::string id(reinterpret_cast<const char*>(key.v), sizeof key.v);
  if (auto it = verified_.find(id); it != verified_.end()) return it->second;
  Sender sender = verify(key);
  // A participant that is not (yet) known is asked again next time.
  if (!sender.subject.empty() || sender.why_not != "unknown participant") verified_[id] = sender;
  return sender;
}

SenderIdentities::Sender SenderIdentities::verify(const dds_guid_t& participant_key) {
  std::string pem;
  bool found = false;
  // Every participant this one knows (a procedure room has a handful).
  constexpr int kBatch = 256;
  std::vector<void*> samples(kBatch, nullptr);
  std::vector<dds_sample_info_t> infos(kBatch);
  const dds_return_t n = dds_read(participants_, samples.data(), infos.data(), kBatch, kBatch);
  for (int i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    const auto* p = static_cast<const dds_builtintopic_participant_t*>(samples[i]);
    if (std::memcmp(p->key.v, participant_key.v, sizeof p->key.v) != 0) continue;
    found = true;
    void* data = nullptr;
    std::size_t size = 0;
    if (p->qos && dds_qget_userdata(p->qos, &data, &size) && data) {
      pem.assign(static_cast<const char*>(data), size);
      dds_free(data);
    }
  }
  if (n > 0) dds_return_loan(participants_, samples.data(), n);
  if (!found) return {"", "unknown participant"};
  if (pem.empty()) return {"", "the participant carries no certificate"};
  auto cert = parsePem(pem);
  if (!cert) return {"", "the participant's USER_DATA is not a PEM certificate"};
  auto ca = parsePem(ca_pem_);
  StorePtr store(X509_STORE_new());
  StoreCtxPtr ctx(X509_STORE_CTX_new());
  if (!ca || !store || !ctx || X509_STORE_add_cert(store.get(), ca.get()) != 1 ||
      X509_STORE_CTX_init(ctx.get(), store.get(), cert.get(), nullptr) != 1) {
    return {"", "cannot set up certificate verification"};
  }
  if (X509_verify_cert(ctx.get()) != 1) {
    return {"", std::string("certificate not signed by our identity CA: ") +
                    X509_verify_cert_error_string(X509_STORE_CTX_get_error(ctx.get()))};
  }
  if (!prefixMatchesSubject(cert.get(), participant_key)) {
    return {"",
            "the certificate is not the one the participant authenticated with (GUID "
            "prefix does not match its subject)"};
  }
  return {subjectOf(cert.get()), ""};
}

}  // namespace ignav::protocol
