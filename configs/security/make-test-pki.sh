#!/usr/bin/env bash
# Creates a TEST public-key infrastructure for ignav's DDS Security: a CA, one identity per role
# (viewer, planner, approver, service), the signed governance and each role's signed permissions.
# For the demo and the tests only: the CA key lies next to its certificate, unprotected. A site
# uses its own CA (docs/SECURITY.md).
#
#   configs/security/make-test-pki.sh OUT_DIR [--ca-name NAME] [--days N] [--robot ID]...
#
# OUT_DIR/<role>/ is an identity folder, what ignav-server and ignavctl take as --identity:
#   identity_ca.pem  permissions_ca.pem  governance.p7s  cert.pem  key.pem  permissions.p7s
#   subject.txt (the certificate's subject, as the permissions grant names it)
# Those hold their role for every robot (the DDS partitions ignav/robot/*). Each --robot ID adds
# OUT_DIR/robots/ID/<role>/, identities (CN=<role>@ID) that hold their role for that robot only:
# an approver of one robot cannot publish an approval to another's server.
# OUT_DIR/ca/ holds the CA's certificate and key (to sign further identities).
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
out=""
ca_name="ignav test CA"
days=365
robots=()
while [ $# -gt 0 ]; do
  case "$1" in
    --ca-name) ca_name="$2"; shift 2 ;;
    --days) days="$2"; shift 2 ;;
    --robot)
      [[ "${2:-}" =~ ^[A-Za-z0-9._-]{1,64}$ ]] || {
        echo "make-test-pki: --robot '${2:-}': a robot id is 1-64 letters, digits, '.', '_', '-'" >&2
        exit 2
      }
      robots+=("$2"); shift 2 ;;
    -h|--help) sed -n 2,15p "$0"; exit 0 ;;
    *) [ -z "$out" ] || { echo "make-test-pki: one OUT_DIR only" >&2; exit 2; }; out="$1"; shift ;;
  esac
done
[ -n "$out" ] || { echo "usage: make-test-pki.sh OUT_DIR [--ca-name NAME] [--days N]" >&2; exit 2; }
command -v openssl >/dev/null || { echo "make-test-pki: openssl is not installed" >&2; exit 2; }

mkdir -p "$out/ca"
ca_key="$out/ca/ca.key"
ca_cert="$out/ca/ca.pem"
quiet() { "$@" 2>/dev/null >/dev/null || { echo "make-test-pki: failed: $*" >&2; exit 1; }; }

# One CA signs identities (identity CA) and governance/permissions (permissions CA); a site may
# keep the two apart. EC P-256: Cyclone's authentication plugin takes RSA-2048 or P-256.
quiet openssl ecparam -name prime256v1 -genkey -noout -out "$ca_key"
quiet openssl req -x509 -new -key "$ca_key" -sha256 -days "$days" -out "$ca_cert" \
  -subj "/C=NL/O=ignav/CN=$ca_name"

quiet openssl smime -sign -text -in "$here/governance.xml" -out "$out/ca/governance.p7s" \
  -signer "$ca_cert" -inkey "$ca_key"

not_before="$(date -u -d '-1 day' +%Y-%m-%dT%H:%M:%S)"
not_after="$(date -u -d "+$days days" +%Y-%m-%dT%H:%M:%S)"

topics_xml() {  # one <topic> line per expression
  for t in "$@"; do printf '            <topic>%s</topic>\n' "$t"; done
}

# identity DIR ROLE CN PARTITION PUBLISH SUBSCRIBE: one identity folder.
identity() {
  local dir="$1" role="$2" cn="$3" partition="$4" publish="$5" subscribe="$6"
  mkdir -p "$dir"
  quiet openssl ecparam -name prime256v1 -genkey -noout -out "$dir/key.pem"
  chmod 600 "$dir/key.pem"
  quiet openssl req -new -key "$dir/key.pem" -out "$dir/cert.csr" -subj "/C=NL/O=ignav/CN=$cn"
  quiet openssl x509 -req -in "$dir/cert.csr" -CA "$ca_cert" -CAkey "$ca_key" -CAcreateserial \
    -sha256 -days "$days" -out "$dir/cert.pem"
  rm -f "$dir/cert.csr"
  subject="$(openssl x509 -in "$dir/cert.pem" -noout -subject -nameopt RFC2253 | sed 's/^subject=//')"
  printf '%s\n' "$subject" >"$dir/subject.txt"
  # shellcheck disable=SC2086  # the topic lists split on spaces on purpose
  pub_xml="$(topics_xml $publish)"
  # shellcheck disable=SC2086
  sub_xml="$(topics_xml $subscribe)"
  awk -v subject="$subject" -v role="$role" -v nb="$not_before" -v na="$not_after" \
    -v pub="$pub_xml" -v subs="$sub_xml" -v partition="$partition" '
      { gsub(/@SUBJECT@/, subject); gsub(/@ROLE@/, role); gsub(/@NOT_BEFORE@/, nb);
        gsub(/@NOT_AFTER@/, na); gsub(/@PARTITION@/, partition) }
      /^@PUBLISH@$/ { print pub; next }
      /^@SUBSCRIBE@$/ { print subs; next }
      { print }' "$here/permissions.xml.in" >"$dir/permissions.xml"
  quiet openssl smime -sign -text -in "$dir/permissions.xml" -out "$dir/permissions.p7s" \
    -signer "$ca_cert" -inkey "$ca_key"
  cp "$ca_cert" "$dir/identity_ca.pem"
  cp "$ca_cert" "$dir/permissions_ca.pem"
  cp "$out/ca/governance.p7s" "$dir/governance.p7s"
}

while read -r role rest; do
  case "$role" in ''|'#'*) continue ;; esac
  publish="${rest%%|*}"
  subscribe="${rest#*|}"
  identity "$out/$role" "$role" "$role" 'ignav/robot/*' "$publish" "$subscribe"
  for robot in "${robots[@]}"; do
    identity "$out/robots/$robot/$role" "$role" "$role@$robot" "ignav/robot/$robot" \
      "$publish" "$subscribe"
  done
done <"$here/roles.txt"

echo "make-test-pki: $out (CA '$ca_name'; identities: $(grep -v '^#' "$here/roles.txt" | awk 'NF{printf "%s ", $1}')${robots[*]:+; for robots only: ${robots[*]}})"
