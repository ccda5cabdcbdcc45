#!/usr/bin/env bash
# Makes a throw-away certificate authority and certificates for trying TLS and mutual TLS
# (the tests use it; a plant uses its own PKI): in DIR,
#   ca.crt / ca.key              the test CA
#   server.crt / server.key      rangexd, for localhost and 127.0.0.1
#   NAME.crt / NAME.key          clients with common name NAME, signed by the CA
#   rogue-ca.crt, rogue-admin.*  a client named "admin" signed by another CA (to be refused)
# usage: scripts/make-test-ca.sh DIR [CLIENT_NAME...]   (default clients: viewer-1
#        operator-1 engineer-1 admin-1 stranger-1)
set -euo pipefail
dir=${1:?usage: scripts/make-test-ca.sh DIR [CLIENT_NAME...]}
shift
clients=("$@")
[ ${#clients[@]} -gt 0 ] || clients=(viewer-1 operator-1 engineer-1 admin-1 stranger-1)
command -v openssl >/dev/null || { echo "make-test-ca: openssl not found (apt-get install openssl)" >&2; exit 1; }
mkdir -p "$dir"
cd "$dir"

key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:prime256v1 -out "$1" 2>/dev/null; }

# sign NAME CA_PREFIX EXTENSIONS: NAME.csr -> NAME.crt
sign() {
  printf '%s\n' "$3" > "$1.ext"
  openssl x509 -req -in "$1.csr" -CA "$2.crt" -CAkey "$2.key" -CAcreateserial -days 30 \
    -sha256 -extfile "$1.ext" -out "$1.crt" 2>/dev/null
  rm -f "$1.csr" "$1.ext"
}

ca() {
  key "$1.key"
  openssl req -x509 -new -key "$1.key" -days 30 -sha256 -subj "/O=rangex test/CN=$2" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
    -out "$1.crt"
}

client() {  # client NAME CA_PREFIX [FILE_PREFIX]
  local f=${3:-$1}
  key "$f.key"
  openssl req -new -key "$f.key" -subj "/O=rangex test/CN=$1" -out "$f.csr"
  sign "$f" "$2" "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=clientAuth"
}

ca ca "rangex test CA"
key server.key
openssl req -new -key server.key -subj "/O=rangex test/CN=rangexd" -out server.csr
sign server ca "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature,keyEncipherment
extendedKeyUsage=serverAuth
subjectAltName=DNS:localhost,IP:127.0.0.1,IP:::1"
for c in "${clients[@]}"; do client "$c" ca; done

ca rogue-ca "rogue CA"
client admin rogue-ca rogue-admin
rm -f ./*.srl
chmod 600 ./*.key
echo "make-test-ca: CA, server and ${#clients[@]} clients (${clients[*]}) in $(pwd)"
