"""`pmsm_hil.dist_version`: the version read without `importlib.metadata` is `importlib.metadata.version`'s, for
every distribution installed here; what it cannot read is asked of `importlib.metadata`; `light_metadata` lets
mcap's writer import without loading `importlib.metadata` and leaves the real one in place afterwards."""

from __future__ import annotations

import json
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

from pmsm_hil import dist_version


def test_every_installed_version_is_importlib_metadatas() -> None:
    names = sorted({dist.metadata["Name"] for dist in metadata.distributions()})
    assert "pmsm-hil" in names and "mcap" in names
    read = {name: dist_version.fast_version(name) for name in names}
    assert read == {name: metadata.version(name) for name in names}
    # other spellings of a name normalise as importlib.metadata's do
    spellings = {dist_version.fast_version(name) for name in ("PMSM_hil", "pmsm.hil", "pmsm--hil")}
    assert spellings == {metadata.version("pmsm-hil")}
    assert dist_version.installed_version("no-such-distribution-here", "unknown") == "unknown"


@pytest.mark.parametrize(("text", "expected", "parser"), [
    ("Metadata-Version: 2.1\nName: x\nVersion: 1.2.3\n\nVersion: 9\n", "1.2.3", "1.2.3"),
    ("Metadata-Version: 2.1\nversion:\t1.0 \n", "1.0 ", "1.0 "),
    ("Name: x\nKeywords: a,\n b\nVersion: 2\n", "2", "2"),  # after another header's folded line
    ("Name: x\n\nVersion: 1\n", None, None),  # in the body, not a header
    ("Name: x\nno header here\nVersion: 1\n", None, None),  # the body begun without a blank line
    ("Name: x\n", None, None),
    # what it leaves to importlib.metadata (None): a folded Version, CR line ends
    ("Name: x\nVersion: 1\n  .2\n", None, "1\n  .2"),
    ("Name: x\r\nVersion: 1\r\n", None, "1"),
])
def test_the_version_header_is_read_as_the_email_parser_reads_it(text: str, expected: str | None,
                                                                 parser: str | None) -> None:
    import email

    assert email.message_from_string(text)["Version"] == parser
    assert dist_version._header_version(text) == expected


def test_a_folder_it_cannot_read_is_asked_of_importlib_metadata(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    info = tmp_path / "Fancy.Pkg-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fancy-pkg\nVersion: 0.1\n  more\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert dist_version.fast_version("fancy_pkg") is None
    assert dist_version.installed_version("fancy-pkg", "unknown") == metadata.version("fancy-pkg")
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fancy-pkg\nVersion: 0.1\n")
    assert dist_version.fast_version("FANCY-pkg") == metadata.version("fancy-pkg") == "0.1"


_MCAP_WRITER = """
import json, sys
from pmsm_hil.dist_version import light_metadata
with light_metadata():
    import mcap.writer
loaded = "importlib.metadata" in sys.modules
from importlib.metadata import PackageNotFoundError, version
print(json.dumps({"library": mcap.writer.LIBRARY_IDENTIFIER, "loaded": loaded, "version": version("mcap"),
                  "real": PackageNotFoundError.__module__}))
"""


def test_mcaps_writer_imports_without_importlib_metadata() -> None:
    proc = subprocess.run([sys.executable, "-c", _MCAP_WRITER], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result == {"library": f"mcap-python/{metadata.version('mcap')}", "loaded": False,
                      "version": metadata.version("mcap"), "real": "importlib.metadata"}
