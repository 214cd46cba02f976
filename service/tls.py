"""Certificates for Dask's TLS between the scheduler, its workers and the API replicas.

The scaled set-up's scheduler runs the pickled callables any connected peer sends it, on
every worker: whoever can open a connection to it runs code as the workers' user (and reads
what they read, the database URL included).  With TLS only peers holding a certificate
signed by the set-up's own CA may connect (mutual TLS, ``distributed.comm.require-encryption``).
This command makes that CA, one certificate for every peer, and the Dask configuration
that uses them::

    python -m service.tls DIR [--if-missing] [--days 825] [--host NAME ...]

It writes ``DIR/ca.pem`` (the CA's certificate), ``DIR/peer.pem`` and ``DIR/peer-key.pem``
(certificate and private key of the peers, mode 0600) and ``DIR/dask.yaml`` (their absolute
paths, ``require-encryption``, ``tls://`` as the default scheme).  Every peer (scheduler,
workers, API replicas) runs with ``DASK_CONFIG=DIR`` and the scheduler's address is
``tls://host:port`` (``PIPEFLOW_SCHEDULER_ADDRESS``).  The CA's private key is not kept (no
certificate can be added later: run the command again and restart every peer);
``--if-missing`` keeps the files of an earlier run (docker-compose.yml runs it at every
``up``).  Dask checks the signature, not host names (``check_hostname`` is off in
:mod:`distributed.security`); the names of ``--host`` (default: the compose services and
localhost) go into the certificate's subjectAltName for other tools.
"""

from __future__ import annotations

import argparse
import datetime
import ipaddress
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: the names in the peers' certificate by default: docker-compose.yml's services, this host
DEFAULT_HOSTS = ("scheduler", "worker", "api1", "api2", "localhost", "127.0.0.1")
#: the certificates' lifetime by default [days] (825: the longest many TLS clients accept)
DEFAULT_DAYS = 825


@dataclass(frozen=True)
class Files:
    """The files :func:`make_certificates` writes."""

    ca: Path
    cert: Path
    key: Path
    config: Path

    @classmethod
    def in_directory(cls, directory: Path) -> Files:
        d = directory.resolve()
        return cls(d / "ca.pem", d / "peer.pem", d / "peer-key.pem", d / "dask.yaml")

    def dask_config(self) -> dict[str, Any]:
        """The Dask configuration of a peer using them (what ``dask.yaml`` holds)."""
        pair = {"cert": str(self.cert), "key": str(self.key)}
        return {
            "distributed": {
                "comm": {
                    "require-encryption": True,
                    "default-scheme": "tls",
                    "tls": {
                        "ca-file": str(self.ca),
                        "scheduler": pair,
                        "worker": pair,
                        "client": pair,
                    },
                }
            }
        }


def make_certificates(
    directory: Path,
    hosts: Sequence[str] = DEFAULT_HOSTS,
    days: int = DEFAULT_DAYS,
    if_missing: bool = False,
) -> Files:
    """Write a fresh CA, a peer certificate signed by it and the Dask configuration using
    them into ``directory`` (created); with ``if_missing``, files already there are kept."""
    import yaml
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    files = Files.in_directory(directory)
    if if_missing and all(p.is_file() for p in (files.ca, files.cert, files.key, files.config)):
        return files
    directory.mkdir(parents=True, exist_ok=True)
    now = datetime.datetime.now(datetime.UTC)
    lifetime = (now - datetime.timedelta(minutes=5), now + datetime.timedelta(days=days))

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "pipeflow dask CA")])
    ca_cert = (
        x509.CertificateBuilder()
        .subject_name(ca_name)
        .issuer_name(ca_name)
        .public_key(ca_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(lifetime[0])
        .not_valid_after(lifetime[1])
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=False,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .sign(ca_key, hashes.SHA256())
    )

    key = ec.generate_private_key(ec.SECP256R1())
    names: list[x509.GeneralName] = []
    for host in hosts:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    cert = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "pipeflow dask peer")]))
        .issuer_name(ca_name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(lifetime[0])
        .not_valid_after(lifetime[1])
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.SubjectAlternativeName(names), critical=False)
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
        .sign(ca_key, hashes.SHA256())
    )

    files.ca.write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))
    files.cert.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    # the private key is created readable by its owner only
    fd = os.open(files.key, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as out:
        out.write(
            key.private_bytes(
                serialization.Encoding.PEM,
                serialization.PrivateFormat.PKCS8,
                serialization.NoEncryption(),
            )
        )
    os.chmod(files.key, 0o600)  # an existing file keeps its mode on open: set it
    files.config.write_text(yaml.safe_dump(files.dask_config(), sort_keys=False))
    return files


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m service.tls",
        description="Make a CA and a certificate for the Dask peers of the scaled set-up.",
    )
    parser.add_argument("directory", type=Path, help="where to write the PEM files")
    parser.add_argument(
        "--host",
        action="append",
        dest="hosts",
        help=f"a name or IP address of the peers (repeatable; default: {' '.join(DEFAULT_HOSTS)})",
    )
    parser.add_argument(
        "--if-missing", action="store_true", help="keep the files of an earlier run if present"
    )
    parser.add_argument(
        "--days", type=int, default=DEFAULT_DAYS, help="lifetime of the certificates [days]"
    )
    args = parser.parse_args(argv)
    files = make_certificates(
        args.directory, args.hosts or DEFAULT_HOSTS, args.days, if_missing=args.if_missing
    )
    print(f"TLS files in {files.config.parent}: peers run with DASK_CONFIG={files.config.parent}")


if __name__ == "__main__":
    main()
