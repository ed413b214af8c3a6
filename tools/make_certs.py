"""Make a private CA and the TLS certificates of the phone + server deployment.

    python tools/make_certs.py OUT_DIR [--host findme.example.org] [--host 192.168.1.20] [--local]

Writes into OUT_DIR (git-ignored when it is certs/; never put it in an image):

* ``ca.pem``  - the private CA (PEM): services and native clients check the router with it
  (``--ca``, ``root_ca_certificate``); ``ca.crt`` - the same in DER, the file to install on
  a phone so that its browser trusts the page (README: "The phone").
* ``router.pem`` / ``router.key`` - the Zenoh router's certificate and key.
* ``gateway.pem`` / ``gateway.key`` - the HTTPS certificate of the phone page's gateway.

Each certificate names the host the compose file gives that service (``router``,
``gateway``), ``localhost`` and ``127.0.0.1``, plus every ``--host`` (DNS names, and IP
addresses as IP subjectAltNames): the names clients use to reach the server. Zenoh and
browsers check the name they connected to against these. Valid 825 days with the
serverAuth extended key usage (iOS refuses server certificates without it or valid longer).
The CA's private key is not kept: to add a host, make a new set (and install the new CA).
Uses the ``cryptography`` package (installed with Find Me); equivalent openssl commands are
in compose/README.md.

``--local`` also writes ``router-local.json5`` and ``service-local.json5`` into OUT_DIR:
compose's Zenoh configurations (router-tls.json5, service-tls.json5) with this folder's
absolute paths instead of the container's ``/certs`` and the router at
``tls/localhost:7447`` instead of the compose host ``router``, to run the same deployment
on one machine without Docker (compose/Procfile.tls, compose/README.md).
"""

from __future__ import annotations

import argparse
import datetime as dt
import ipaddress
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

COMPOSE = Path(__file__).resolve().parents[1] / "compose"
#: The services of compose/docker-compose.yml that serve TLS, by their compose host names.
COMPOSE_TLS_HOSTS = ("router", "gateway")
LOCAL = ("localhost", "127.0.0.1")


def _name(cn: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])


def _san(host: str) -> x509.GeneralName:
    try:
        return x509.IPAddress(ipaddress.ip_address(host))
    except ValueError:
        return x509.DNSName(host)


def _write_key(path: Path, key) -> None:
    path.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                       serialization.PrivateFormat.PKCS8,
                                       serialization.NoEncryption()))
    path.chmod(0o600)


def make_certs(out: Path, hosts=(), leaves: dict | None = None, days: int = 825) -> dict:
    """Write the CA and one certificate per leaf into ``out``; returns {name: path}.

    Args:
        hosts: extra host names / IP addresses every certificate names.
        leaves: {file stem: [host, ...]} (default: ``router`` and ``gateway``, each naming
            itself, localhost, 127.0.0.1 and ``hosts``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if leaves is None:
        leaves = {stem: [stem, *LOCAL, *hosts] for stem in COMPOSE_TLS_HOSTS}
    now = dt.datetime.now(dt.timezone.utc)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_ski = x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key())
    ca = (x509.CertificateBuilder().subject_name(_name("Find Me private CA"))
          .issuer_name(_name("Find Me private CA")).public_key(ca_key.public_key())
          .serial_number(x509.random_serial_number()).not_valid_before(now)
          .not_valid_after(now + dt.timedelta(days=days))
          .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
          .add_extension(x509.KeyUsage(digital_signature=False, content_commitment=False,
                                       key_encipherment=False, data_encipherment=False,
                                       key_agreement=False, key_cert_sign=True, crl_sign=True,
                                       encipher_only=False, decipher_only=False), critical=True)
          .add_extension(ca_ski, critical=False)
          .sign(ca_key, hashes.SHA256()))
    paths = {"ca": out / "ca.pem", "ca_der": out / "ca.crt"}
    paths["ca"].write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    paths["ca_der"].write_bytes(ca.public_bytes(serialization.Encoding.DER))
    for stem, names in leaves.items():
        names = list(dict.fromkeys(names))      # in order, once each
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (x509.CertificateBuilder().subject_name(_name(names[0])).issuer_name(ca.subject)
                .public_key(key.public_key()).serial_number(x509.random_serial_number())
                .not_valid_before(now).not_valid_after(now + dt.timedelta(days=days))
                .add_extension(x509.SubjectAlternativeName([_san(h) for h in names]), critical=False)
                .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
                .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH]),
                               critical=False)
                .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()),
                               critical=False)
                .add_extension(x509.AuthorityKeyIdentifier.from_issuer_subject_key_identifier(ca_ski),
                               critical=False)
                .sign(ca_key, hashes.SHA256()))
        paths[stem] = out / f"{stem}.pem"
        paths[stem].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        paths[stem + "_key"] = out / f"{stem}.key"
        _write_key(paths[stem + "_key"], key)
    return paths


def local_configs(out: Path, connect: str = "tls/localhost:7447",
                  listen: str = "tls/0.0.0.0:7447") -> dict:
    """Write ``out/router-local.json5`` and ``out/service-local.json5``: compose's TLS
    configurations with ``out``'s absolute paths, the router listening on ``listen`` and the
    services connecting to ``connect``; returns {"router": path, "service": path}."""
    out = Path(out).resolve()
    certs = f"{out}/"
    router = (COMPOSE / "router-tls.json5").read_text()
    service = (COMPOSE / "service-tls.json5").read_text()
    for text, what in ((router, '"/certs/'), (router, '"tls/0.0.0.0:7447"'),
                       (service, '"/certs/'), (service, '"tls/router:7447"')):
        if what not in text:     # compose's files changed: say so rather than write a wrong one
            raise SystemExit(f"compose's Zenoh configuration no longer has {what}")
    header = ("// Made by tools/make_certs.py --local from compose/{} for this machine: edit "
              "that one, then make it again.\n")
    paths = {"router": out / "router-local.json5", "service": out / "service-local.json5"}
    paths["router"].write_text(header.format("router-tls.json5") + router.replace(
        '"/certs/', f'"{certs}').replace('"tls/0.0.0.0:7447"', f'"{listen}"'))
    paths["service"].write_text(header.format("service-tls.json5") + service.replace(
        '"/certs/', f'"{certs}').replace('"tls/router:7447"', f'"{connect}"'))
    return paths


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", help="folder to write the files into (e.g. certs)")
    ap.add_argument("--host", action="append", default=[],
                    help="a name or IP address clients use to reach the server (repeatable)")
    ap.add_argument("--local", action="store_true",
                    help="also write router-local.json5 and service-local.json5, the TLS "
                         "deployment's Zenoh configurations for this machine (no Docker)")
    a = ap.parse_args(argv)
    paths = make_certs(Path(a.out), tuple(a.host))
    if a.local:
        paths.update({f"{k}_config": v for k, v in local_configs(Path(a.out)).items()})
    names = [*COMPOSE_TLS_HOSTS, *LOCAL, *a.host]
    print("\n".join(f"{k}: {v}" for k, v in paths.items()))
    print(f"certificates name: {', '.join(dict.fromkeys(names))}")


if __name__ == "__main__":
    main()
