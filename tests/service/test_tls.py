"""Dask TLS of the scaled set-up (:mod:`service.tls`): a scheduler using the files of one
run accepts peers holding that run's certificate and refuses a peer with a certificate of
another CA, and one speaking plain TCP (real Dask comms in this process)."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest
from distributed import Client, Scheduler, Worker
from distributed.security import Security

from service.tls import Files, make_certificates


def _security(files: Files) -> Security:
    return Security(
        require_encryption=True,
        tls_ca_file=str(files.ca),
        tls_scheduler_cert=str(files.cert),
        tls_scheduler_key=str(files.key),
        tls_worker_cert=str(files.cert),
        tls_worker_key=str(files.key),
        tls_client_cert=str(files.cert),
        tls_client_key=str(files.key),
    )


def test_only_peers_of_the_same_ca_connect(tmp_path: Path) -> None:
    ours = _security(make_certificates(tmp_path / "ours", days=1))
    theirs = _security(make_certificates(tmp_path / "theirs", days=1))

    async def scenario() -> None:
        async with Scheduler(
            protocol="tls", host="127.0.0.1", dashboard=False, security=ours
        ) as scheduler:
            address = scheduler.address
            assert address.startswith("tls://")
            async with (
                Worker(address, nthreads=1, security=ours),
                Client(address, security=ours, asynchronous=True) as client,
            ):
                assert await client.submit(pow, 2, 10) == 1024
            with pytest.raises(OSError):  # TLS handshake refused: unknown CA
                await Client(address, security=theirs, asynchronous=True, timeout="3s")
            with pytest.raises(OSError):  # plain TCP to the TLS port
                await Client(address.replace("tls://", "tcp://"), asynchronous=True, timeout="3s")

    asyncio.run(scenario())


def test_key_is_private_and_config_names_the_files(tmp_path: Path) -> None:
    files = make_certificates(tmp_path, hosts=["scheduler", "10.0.0.7"], days=1)
    assert files.key.stat().st_mode & 0o777 == 0o600
    comm = files.dask_config()["distributed"]["comm"]
    assert comm["require-encryption"] is True
    assert comm["tls"]["ca-file"] == str(files.ca)
    from cryptography import x509

    cert = x509.load_pem_x509_certificate(files.cert.read_bytes())
    ca = x509.load_pem_x509_certificate(files.ca.read_bytes())
    cert.verify_directly_issued_by(ca)  # raises if not signed by the CA
    names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert "scheduler" in names.get_values_for_type(x509.DNSName)
