"""mrta_zenoh.shared_reads: inside the scope a file is read once per version of it; outside, or
once it changed, it is read again; a failed read is not remembered."""

import pytest

from mrta_zenoh.shared_reads import once, shared_reads


def test_a_file_is_read_once_per_version_inside_the_scope(tmp_path):
    path, reads = tmp_path / "f.yaml", []

    def read():
        reads.append(path.read_text())
        return object()

    path.write_text("a: 1\n")
    assert once(path, "x", read) is not once(path, "x", read)  # no scope: each call reads
    reads.clear()
    with shared_reads():
        first = once(path, "x", read)
        with shared_reads():  # a nested scope shares the outer one's reads
            assert once(path, "x", read) is first
        assert once(path, "y", read) is not first  # another reader of the same file
        path.write_text("a: 22\n")  # another version: read again
        assert once(path, "x", read) is not first
    assert reads == ["a: 1\n", "a: 1\n", "a: 22\n"]
    assert once(path, "x", read) is not once(path, "x", read)  # the scope ended


def test_a_failed_read_is_not_remembered(tmp_path):
    path, calls = tmp_path / "f.yaml", []
    path.write_text("x")

    def read():
        calls.append(1)
        raise ValueError("bad")

    with shared_reads():
        for _ in range(2):
            with pytest.raises(ValueError):
                once(path, "x", read)
        with pytest.raises(FileNotFoundError):  # a missing file: the reader's own error
            once(tmp_path / "missing", "x", lambda: open(tmp_path / "missing"))
    assert len(calls) == 2
