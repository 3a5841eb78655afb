"""The C++ component's MCAP writer (templates/cpp/hfsmc/mcap.hpp), read back with the
Python ``mcap`` reader.

tests/cpp/mcap_main.cpp is built once per module with g++ (-Wall -Wextra -Werror,
AddressSanitizer and UBSan); each test has it write a file and reads it with the
library's readers: the seeking one (make_reader on a file, through the summary) and the
streaming ones (StreamReader, NonSeekingReader), which read a file with no footer up to
where it was cut.  schemas/recording.md describes the layout."""

from __future__ import annotations

import io
import os
import shutil
import signal
import struct
import subprocess
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import pytest
from mcap.exceptions import EndOfFile, McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import (
    Channel,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import StreamReader

from tests.conftest import ROOT

pytestmark = pytest.mark.timeout(180)

MAGIC = b"\x89MCAP0\r\n"
FLAGS = ["-std=c++17", "-Wall", "-Wextra", "-Werror", "-Wpedantic", "-Wconversion", "-O1", "-g",
         "-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer"]
# A cut file ends the streaming readers with one of these: EndOfFile, struct.error (a cut
# in a fixed-size field), UnicodeDecodeError (a cut inside a non-ASCII string).
CUT_ERRORS = (McapError, struct.error, UnicodeDecodeError)
# make_reader on a seekable cut file reads a "footer" from the last bytes, follows its
# offsets into the data and fails with anything of these (UnicodeDecodeError among them).
SEEKING_ERRORS = (McapError, struct.error, ValueError)


@pytest.fixture(scope="module")
def writer(tmp_path_factory: pytest.TempPathFactory) -> Path:
    gxx = shutil.which("g++")
    if gxx is None:
        pytest.fail("g++ is needed to test the C++ MCAP writer (`make deps` installs it)")
    exe = tmp_path_factory.mktemp("mcap") / "mcap_main"
    cmd = [gxx, *FLAGS, "-I", str(ROOT / "templates" / "cpp"),
           str(ROOT / "tests" / "cpp" / "mcap_main.cpp"), "-o", str(exe)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=240, check=False)
    assert done.returncode == 0, done.stderr
    return exe


def run(exe: Path, *args: str | Path) -> None:
    done = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True,
                          timeout=120, check=False)
    assert done.returncode == 0, done.stderr


def payload(t: int, c: int) -> bytes:
    """The bytes mcap_main.cpp's payload(t, c) writes."""
    return f"t={t} c={c}".encode() + b"\0" + bytes([(t * 7 + c) % 256]) * ((t + c) % 50)


def tick_messages(n: int) -> list[tuple[int, int, int, bytes]]:
    """(channel, sequence, log_time, data) of `mcap_main ticks FILE n`, in file order."""
    return [(c, t, 1_000_000 * t, payload(t, c)) for t in range(n) for c in range(3)]


def streamed(source: IO[bytes]) -> tuple[list[McapRecord], Exception | None]:
    """The records a StreamReader yields (CRCs checked), and the error that ended it, if any."""
    records: list[McapRecord] = []
    try:
        for record in StreamReader(source, validate_crcs=True).records:
            records.append(record)
    except CUT_ERRORS as e:
        return records, e
    return records, None


def messages(records: list[McapRecord]) -> list[tuple[int, int, int, bytes]]:
    return [(m.channel_id, m.sequence, m.log_time, m.data) for m in records if isinstance(m, Message)]


def summary_records(data: bytes, footer: Footer) -> Iterator[tuple[int, McapRecord]]:
    """(offset, record) of the summary section, from the footer's summary_start to the footer."""
    offset, end = footer.summary_start, len(data) - len(MAGIC) - (1 + 8 + 20)
    while offset < end:
        length = struct.unpack_from("<Q", data, offset + 1)[0]
        one = data[offset:offset + 9 + length]
        yield offset, next(iter(StreamReader(io.BytesIO(one), skip_magic=True).records))
        offset += 9 + length
    assert offset == end


def test_every_record_type_reads_back(writer: Path, tmp_path: Path) -> None:
    path = tmp_path / "all.mcap"
    run(writer, "all", path)
    data = path.read_bytes()
    assert data.startswith(MAGIC) and data.endswith(MAGIC)

    every, error = streamed(io.BytesIO(data))
    assert error is None
    records = every[:next(i for i, r in enumerate(every) if isinstance(r, DataEnd)) + 1]  # data section
    assert records[0] == Header(profile="hfsmc-test", library="hfsmc mcap.hpp test")
    schemas = [r for r in records if isinstance(r, Schema)]
    assert schemas == [Schema(id=1, name="hfsmc.Tick", encoding="jsonschema", data=b'{"type":"object"}'),
                       Schema(id=2, name="", encoding="", data=b""),
                       Schema(id=3, name="bin", encoding="x-bytes", data=b"\0\x01\xff\0")]
    channels = [r for r in records if isinstance(r, Channel)]
    assert len(channels) == 303
    assert channels[0] == Channel(id=0, schema_id=1, topic="/tick", message_encoding="json",
                                  metadata={"model": "follow_colors.yaml", "note": "vol à 日"})
    assert channels[1] == Channel(id=1, schema_id=2, topic="", message_encoding="", metadata={})
    assert channels[2] == Channel(id=2, schema_id=0, topic="/no_schema", message_encoding="x-bytes",
                                  metadata={})
    assert [c.topic for c in channels[3:]] == [f"/many/{c}" for c in range(300)]
    metadata = [r for r in records if isinstance(r, Metadata)]
    assert metadata == [Metadata(name="hfsmc", metadata={"version": "0.1", "été": "✓", "": ""}),
                        Metadata(name="", metadata={})]

    large = bytes((i * 131) % 251 for i in range(5 << 20))
    many = [(3 + c, t, 10000 + t, payload(t, c)) for t in range(3) for c in range(300)]
    assert messages(records) == [(0, 0, 1000, b'{"tick":1}'), (1, 0, 1000, b""),
                                 (2, 0, 2000, b"\0\x01\xff\0"), (2, 1, 3000, large),
                                 *many, (0, 1, 500, b'{"tick":0}')]
    published = [m.publish_time for m in records if isinstance(m, Message)]
    assert published[:3] == [1000, 1000, 1500]
    data_end = next(r for r in records if isinstance(r, DataEnd))
    cut = data.index(b"\x0f" + struct.pack("<Q", 4) + struct.pack("<I", data_end.data_section_crc))
    assert data_end.data_section_crc == zlib.crc32(data[:cut]) != 0

    # The summary, as the seeking reader finds it from the footer.
    with path.open("rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics == Statistics(
            message_count=905, schema_count=3, channel_count=303, attachment_count=0, metadata_count=2,
            chunk_count=0, message_start_time=500, message_end_time=10002,
            channel_message_counts={0: 2, 1: 1, 2: 2, **{3 + c: 3 for c in range(300)}})
        assert list(summary.channels.values()) == channels
        assert list(summary.schemas.values()) == schemas
        in_file = [(c.id, m.sequence, m.log_time, m.data)
                   for _, c, m in reader.iter_messages(log_time_order=False)]
        assert in_file == messages(records)
        by_time = [m.log_time for _, _, m in reader.iter_messages()]
        assert by_time == sorted(by_time) and by_time[0] == 500
        assert [m.name for m in reader.iter_metadata()] == ["hfsmc", ""]

    footer = every[-1]
    assert isinstance(footer, Footer)
    summary_bytes = data[footer.summary_start:len(data) - len(MAGIC) - 4]  # through summary_offset_start
    assert footer.summary_crc == zlib.crc32(summary_bytes) != 0
    found = list(summary_records(data, footer))
    offsets = [(o, r) for o, r in found if isinstance(r, SummaryOffset)]
    assert offsets and offsets[0][0] == footer.summary_offset_start
    groups = {r.group_opcode: r for _, r in offsets}
    assert sorted(groups) == [0x03, 0x04, 0x0B, 0x0D]
    for opcode, group in groups.items():  # each group starts with a record of its opcode
        assert data[group.group_start] == opcode
        inside = [r for o, r in found if group.group_start <= o < group.group_start + group.group_length]
        assert inside and all(type(r) is type(inside[0]) for r in inside)
    for index in (r for _, r in found if isinstance(r, MetadataIndex)):
        assert data[index.offset] == 0x0C
        assert struct.unpack_from("<Q", data, index.offset + 1)[0] == index.length - 9


def test_a_file_cut_at_any_byte_reads_up_to_the_cut(writer: Path, tmp_path: Path) -> None:
    path = tmp_path / "ticks.mcap"
    run(writer, "ticks", path, "4")
    data = path.read_bytes()
    full, error = streamed(io.BytesIO(data))
    assert error is None and messages(full) == tick_messages(4)
    header_end = len(MAGIC) + 9 + struct.unpack_from("<Q", data, len(MAGIC) + 1)[0]
    ends: set[str] = set()
    for cut in range(header_end, len(data)):
        part = data[:cut]
        records, error = streamed(io.BytesIO(part))
        assert error is not None, cut  # every cut loses at least the closing magic
        ends.add(type(error).__name__)
        assert records == full[:len(records)], cut
        got = messages(records)
        assert got == tick_messages(4)[:len(got)], cut
        # the non-seeking reader stops at the cut in the same way
        seen: list[tuple[int, int, int, bytes]] = []
        with pytest.raises(CUT_ERRORS):
            for _, channel, m in NonSeekingReader(io.BytesIO(part)).iter_messages(log_time_order=False):
                seen.append((channel.id, m.sequence, m.log_time, m.data))
        assert seen == got, cut
        # make_reader on a seekable file looks for the footer at the end and fails
        with pytest.raises(SEEKING_ERRORS):
            list(make_reader(io.BytesIO(part)).iter_messages())
    assert ends == {"EndOfFile", "error", "UnicodeDecodeError"}, ends


def kill_9_after(args: list[str], lines: int) -> list[str]:
    """Run the writer with ``args``, read ``lines`` lines of its output, then kill -9 it."""
    with subprocess.Popen(args, stdout=subprocess.PIPE, text=True) as proc:
        try:
            assert proc.stdout is not None
            got = [proc.stdout.readline() for _ in range(lines)]
            os.kill(proc.pid, signal.SIGKILL)
            assert proc.wait(timeout=30) == -signal.SIGKILL
        finally:
            if proc.poll() is None:
                proc.kill()
    return got


def test_kill_9_after_a_flush_leaves_every_tick(writer: Path, tmp_path: Path) -> None:
    path = tmp_path / "open.mcap"
    lines = kill_9_after([str(writer), "ticks", str(path), "50", "open"], 51)
    assert lines[-1] == "waiting\n", lines
    with path.open("rb") as f:
        records, error = streamed(f)
    assert isinstance(error, EndOfFile)  # at a record boundary: no DataEnd, no footer
    assert messages(records) == tick_messages(50)
    assert not any(isinstance(r, DataEnd | Footer) for r in records)


def test_kill_9_mid_run_leaves_a_readable_prefix(writer: Path, tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    # killed while it is still writing
    lines = kill_9_after([str(writer), "ticks", str(path), "1000000"], 200)
    assert all(line.startswith("tick ") for line in lines), lines[-3:]
    with path.open("rb") as f:
        records, error = streamed(f)
    assert error is not None
    got = messages(records)
    assert len(got) >= 200 * 3  # every tick reported flushed is there
    assert got == tick_messages(len(got) // 3 + 1)[:len(got)]


def test_a_file_that_cannot_be_created_is_an_error(writer: Path, tmp_path: Path) -> None:
    path = tmp_path / "missing" / "x.mcap"
    done = subprocess.run([str(writer), "ticks", str(path), "1"], capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == 1
    assert done.stderr == f"mcap_main: {path}: No such file or directory\n"
