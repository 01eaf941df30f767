"""The text encoding of a CSV file: UTF-8 as it is, the 8-bit encodings Windows tools write
read with a warning, anything else refused with the byte and the line (docs/ingest.md)."""

from __future__ import annotations

import numpy as np

from flightrecon.errors import InputFileError

#: 8-bit encodings Windows tools write, tried in this order on a file that is not UTF-8
#: (Windows-1252 is Latin-1 with printable characters where Latin-1 has C1 controls)
LEGACY_ENCODINGS = ("cp1252",)
#: bytes Windows-1252 leaves undefined (Latin-1's C1 controls there: never text)
_CP1252_UNDEFINED = frozenset(b"\x81\x8d\x8f\x90\x9d")


def _where(raw: bytes, pos: int) -> str:
    line = raw.count(b"\n", 0, pos) + 1
    return f"byte offset {pos} (line {line})"


def decode_text(raw: bytes, file: str) -> tuple[bytes, str | None]:
    """``raw`` as UTF-8 bytes without a BOM, and the warning when it was not UTF-8.

    UTF-8 (with or without its BOM) is read as it is.  A file that is not UTF-8 but decodes as
    Windows-1252 (or Latin-1, its printable subset from 0xA0: the degree sign 0xB0 of a header
    such as ``OAT (\u00b0C)``) is read in that encoding with a warning naming it and its first
    such byte.  Refused (:class:`InputFileError`, exit 3, naming the byte offset and the line):
    UTF-16, NUL bytes (binary), bytes no 8-bit text encoding gives (0x81, 0x8D, 0x8F, 0x90,
    0x9D: C1 control codes), and a file mixing UTF-8 with another encoding.
    """
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise InputFileError("file is UTF-16 encoded; re-save it as UTF-8 (CSV text)", file=file)
    nul = raw.find(b"\x00", 0, 1 << 20)
    if nul >= 0:
        raise InputFileError(f"not a text file: NUL byte at {_where(raw, nul)}; binary data or "
                             "a wrong encoding", file=file)
    bom = 3 if raw[:3] == b"\xef\xbb\xbf" else 0
    body = raw[bom:]
    if not body or int(np.frombuffer(body, dtype=np.uint8).max()) < 0x80:
        return body, None            # plain ASCII (the usual case): valid UTF-8, no decoding
    try:
        body.decode("utf-8")
        return body, None
    except UnicodeDecodeError as exc:
        pos = bom + exc.start
    high = np.flatnonzero(np.frombuffer(raw[:pos], dtype=np.uint8) >= 0x80)
    if bom or high.size:
        raise InputFileError(f"not valid UTF-8 at {_where(raw, pos)} (byte 0x{raw[pos]:02X}), "
                             "although the text before it is UTF-8: mixed encodings; re-save "
                             "it as UTF-8", file=file)
    bad = next((i for i in range(pos, len(raw)) if raw[i] in _CP1252_UNDEFINED), None)
    if bad is not None:
        raise InputFileError(f"byte 0x{raw[bad]:02X} at {_where(raw, bad)} is text in no "
                             "encoding flightrecon reads (not UTF-8, Windows-1252 or Latin-1: "
                             "a C1 control code; binary data?)", file=file)
    text = body.decode(LEGACY_ENCODINGS[0])
    c1 = np.frombuffer(body, dtype=np.uint8)
    name = ("Windows-1252" if ((c1 >= 0x80) & (c1 < 0xA0)).any()
            else "Windows-1252 / Latin-1 (ISO-8859-1)")
    return text.encode("utf-8"), (f"{file}: not UTF-8: read as {name} (first byte outside "
                                  f"UTF-8: 0x{raw[pos]:02X} '{raw[pos:pos + 1].decode('cp1252')}'"
                                  f" at {_where(raw, pos)}); re-save it as UTF-8 to be sure of "
                                  "its text")
