"""Certificates and Zenoh configurations for the TLS and access-control tests (docs/remote.md, "Security").

A cell's certificate authority signs the server's certificate (names ``localhost`` and 127.0.0.1, so a client
verifies it) and one certificate per client identity (its common name is what Zenoh's access control
matches: ``cert_common_names``). A second authority stands for anyone else. Written with the ``cryptography``
package; docs/remote.md gives the same steps with openssl.
"""

from __future__ import annotations

import datetime
import ipaddress
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("cryptography")

from cryptography import x509  # noqa: E402
from cryptography.hazmat.primitives import hashes, serialization  # noqa: E402
from cryptography.hazmat.primitives.asymmetric import ec  # noqa: E402
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID  # noqa: E402


def _name(cn: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])


def _builder(cn: str, issuer: x509.Name, key: Any) -> x509.CertificateBuilder:
    now = datetime.datetime.now(datetime.UTC)
    return (
        x509.CertificateBuilder()
        .subject_name(_name(cn))
        .issuer_name(issuer)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=1))
    )


def _write(folder: Path, cn: str, key: Any, cert: x509.Certificate) -> None:
    pkcs8 = serialization.PrivateFormat.PKCS8
    pem = serialization.Encoding.PEM
    (folder / f"{cn}.key").write_bytes(key.private_bytes(pem, pkcs8, serialization.NoEncryption()))
    (folder / f"{cn}.pem").write_bytes(cert.public_bytes(pem))


class Authority:
    """A certificate authority that writes ``NAME.pem`` and ``NAME.key`` into ``folder``."""

    def __init__(self, folder: Path, cn: str) -> None:
        self.folder, self.cn = folder, cn
        self.key = ec.generate_private_key(ec.SECP256R1())
        usage = x509.KeyUsage(
            digital_signature=True,
            key_cert_sign=True,
            crl_sign=True,
            content_commitment=False,
            key_encipherment=False,
            data_encipherment=False,
            key_agreement=False,
            encipher_only=False,
            decipher_only=False,
        )
        self.cert = (
            _builder(cn, _name(cn), self.key)
            .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
            .add_extension(usage, critical=True)
            .sign(self.key, hashes.SHA256())
        )
        _write(folder, cn, self.key, self.cert)

    @property
    def pem(self) -> Path:
        return self.folder / f"{self.cn}.pem"

    def issue(self, cn: str, *, server: bool = False) -> None:
        key = ec.generate_private_key(ec.SECP256R1())
        purpose = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
        builder = (
            _builder(cn, self.cert.subject, key)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.ExtendedKeyUsage([purpose]), critical=False)
        )
        if server:
            names = [x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
            builder = builder.add_extension(x509.SubjectAlternativeName(names), critical=False)
        _write(self.folder, cn, key, builder.sign(self.key, hashes.SHA256()))


SERVER_CONFIG = """{
  transport: { link: { tls: {
    root_ca_certificate: "%(ca)s",
    listen_certificate: "%(dir)s/server.pem",
    listen_private_key: "%(dir)s/server.key",
    enable_mtls: true,
  } } },
  access_control: {
    enabled: true,
    default_permission: "deny",
    rules: [
      { id: "observe", permission: "allow", flows: ["ingress"],
        messages: ["query", "declare_subscriber", "liveliness_token", "declare_liveliness_subscriber",
                   "liveliness_query"],
        key_exprs: ["grippers/*", "grippers/*/state", "grippers/*/info", "grippers/*/client/*"] },
      { id: "serve", permission: "allow", flows: ["egress"],
        messages: ["put", "delete", "reply", "declare_queryable", "liveliness_token", "declare_subscriber",
                   "declare_liveliness_subscriber", "liveliness_query"],
        key_exprs: ["grippers/**"] },
      { id: "command", permission: "allow", flows: ["ingress"], messages: ["query"],
        key_exprs: ["grippers/*/cmd/**"] },
    ],
    subjects: [
      { id: "cell", cert_common_names: ["controller", "observer"] },
      { id: "controller", cert_common_names: ["controller"] },
    ],
    policies: [
      { rules: ["observe", "serve"], subjects: ["cell"] },
      { rules: ["command"], subjects: ["controller"] },
    ],
  },
}
"""

CLIENT_CONFIG = """{
  transport: { link: { tls: {
    root_ca_certificate: "%(ca)s",
    enable_mtls: true,
    connect_certificate: "%(dir)s/%(who)s.pem",
    connect_private_key: "%(dir)s/%(who)s.key",
  } } },
}
"""

NO_CERT_CONFIG = """{ transport: { link: { tls: { root_ca_certificate: "%(ca)s" } } } }
"""


def make_cell(folder: Path) -> dict[str, Path]:
    """The cell's CA, the server's and two clients' certificates (controller, observer), an intruder's from
    another CA; the JSON5 files of the server and of each client (and of one without a certificate)."""
    cell = Authority(folder, "cell-ca")
    cell.issue("server", server=True)
    cell.issue("controller")
    cell.issue("observer")
    Authority(folder, "rogue-ca").issue("intruder")
    values = {"ca": str(cell.pem), "dir": str(folder)}
    files = {"server": folder / "server.json5", "no-cert": folder / "no-cert.json5"}
    files["server"].write_text(SERVER_CONFIG % values)
    files["no-cert"].write_text(NO_CERT_CONFIG % values)
    for who in ("controller", "observer", "intruder"):
        files[who] = folder / f"{who}.json5"
        files[who].write_text(CLIENT_CONFIG % {**values, "who": who})
    return files
