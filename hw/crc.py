"""CRC-16/CCITT-FALSE of the serial frames (poly 0x1021, init 0xFFFF, no reflection, no final xor).

The standard library's :func:`binascii.crc_hqx` is this CRC (table-driven, in C);
its check value is ``crc16(b"123456789") == 0x29B1``.
"""

from __future__ import annotations

import binascii

__all__ = ["crc16", "CRC16_INIT", "CRC16_CHECK"]

CRC16_INIT = 0xFFFF
CRC16_CHECK = 0x29B1  # crc16(b"123456789")


def crc16(data: bytes | bytearray | memoryview, crc: int = CRC16_INIT) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (an int in [0, 0xFFFF]); ``crc`` continues a running CRC."""
    return binascii.crc_hqx(data, crc)
