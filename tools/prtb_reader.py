#!/usr/bin/env python3
"""Independent reader and validator for PRT bake files (`.prtb`, format 1.x).

This reader was written from `crates/bakefile/SPEC.md` (format version 1.1) ALONE: it does not
import, call or mirror the Rust crate `prt-bakefile`, and no Rust source was read while writing
it. Its value is that it is a second, clean-room implementation of the specification, so that a
disagreement between it and the crate points at a bug in one of them or at an ambiguity of
SPEC.md. Section numbers (§n) below refer to SPEC.md.

It reads the three sample kinds of §3.1: per-vertex bakes (kind 1), per-pixel bakes (kind 2,
with the `camera` and a `CVRG` coverage section per object) and per-texel (lightmap) bakes
(kind 3: objects with a `CVRG` are lightmapped, one point per texel of their own W×H lightmap,
`K = 1`, hits 0/1, no sum over objects; objects without one are per-vertex; `settings.lightmaps`
describes each object's lightmap), in f32 or f16, sharded or not, 1.0 or 1.1 files, including
`MESH` geometry (hash recomputed) and blocks compressed by clustered PCA (`CPCA`, §3.13).

Reflectance fields (`RFLD`, §3.14, written by `prt reflectance`) are read and validated: the
section is REQUIRED, 1.1, once at most, only in an unsharded per-pixel file with no objects;
W ≥ 2, H ≥ 1, W·H ≤ 2²⁴, channels 3, P ≤ image pixels and the exact length
`32 + 4P + size·3WHP` before any array is viewed; pixel indices strictly increasing and inside
the image; every value (f32 or f16, the file's scalar type) finite and ≥ 0; and
`settings.pixel_samples` plus `settings.reflectance` (directions = RFLD's W, H; bounces = BINF;
rays = BINF rays_per_point; pixel_samples = settings.pixel_samples; geometry a non-empty list of
uniquely named meshes with well-formed hashes), which no file without a field may carry. Fields
are not relit here (§3.14 leaves the quadrature of ∫R·L dω undefined).

Requirements: Python 3.11 standard library + numpy (`tools/requirements-reader.txt`).

Usage
-----
    python3 tools/prtb_reader.py FILE.prtb
        Parse and validate the whole file (every rule of §4, in that order, and the section
        rules of §2/§3). Exit 0 if valid; otherwise print ONE line
        `prtb_reader: FILE: <what is wrong>` to stderr and exit 1.

    python3 tools/prtb_reader.py FILE.prtb --dump OUT.json
        Also write a JSON summary of the file (see `dump()`); its `sample_kind` is "vertex",
        "pixel" or "texel", with `width`/`height` the BINF image or lightmap size (0 × 0 for
        per-vertex bakes). Blocks compressed by clustered PCA (`CPCA`, §3.13) are
        reconstructed in f32 exactly as §3.13 says and summarised like `XFER` blocks, plus a
        `cpca` entry (clusters, components, dimension, rel_error). `reflectance` is null, or
        for a file with a reflectance field (`RFLD`, §3.14) its directions `[W, H]`, channels,
        scalar type, pixel count, first/last pixel, CRC-32s of the pixel indices (u32 LE) and
        of the values widened to f32 (LE, file order), their sum, max and count of zeros.

    python3 tools/prtb_reader.py FILE.prtb --field-out OUT.bin
        Also write a reflectance field raw: the P held pixel indices (u32 LE), then the
        3·W·H·P values widened to f32 LE, `[pixel held][channel][direction]` (exact for f16).

    python3 tools/prtb_reader.py FILE.prtb --relight OBJECT --albedo R,G,B [--order N] \
            --colours OUT.csv
        Also relight OBJECT's points under the file's environment (ENVL) with its diffuse
        transfer (§3.4, §3.6) and write `point,r,g,b` rows (float64, repr() precision). The
        points are vertices, pixels (`y × width + x`) or, for a lightmapped object of a
        per-texel bake, texels of its lightmap (`y × width + x`; texels whose hits are 0 have
        zero transfer and so relight to 0).

    python3 tools/prtb_reader.py --self-test FILE.prtb [--seed S]
        Corruption self-check on a VALID file: single-byte flips (every header/table byte, every
        payload edge, zero padding, random positions), truncations and extensions, and mutations
        whose CRCs are repaired (so the semantic checks are exercised; for CPCA blocks also
        targeted ones that break a §3.13 rule and must be refused; for per-texel bakes also
        targeted binary and META JSON mutations that break a §3.1/§3.9/§3.11 rule, the META
        section being rewritten at its new length with the following sections moved; for
        files with a reflectance field likewise targeted RFLD/BINF/flags and
        `settings.reflectance` mutations that break a §3.14 rule, plus allowed controls). Prints
        the figures and exits 1 if a corruption that must be refused was accepted, or if any
        input crashed the reader (any exception other than a clean validation error).

Exit status: 0 valid / done, 1 invalid file or bad arguments (one line on stderr).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import re
import struct
import subprocess
import sys
import tempfile
import traceback
import zlib

try:
    import numpy as np
except ImportError:  # a clean one-line message, never a traceback
    sys.stderr.write("prtb_reader: numpy is required (pip install -r tools/requirements-reader.txt)\n")
    sys.exit(1)

PROG = "prtb_reader"

MAGIC = b"PRTBAKE\x00"
KNOWN_MAJOR = 1
HEADER_SIZE = 64
ENTRY_SIZE = 32
NONE_INDEX = 0xFFFFFFFF
U32_MAX = 2**32 - 1
U64_MAX = 2**64 - 1
FLAG_REQUIRED = 1
UNDERSTOOD_MASK = 0xFFFF  # §6: bits 0-15 must be understood, bits 16-31 are ignorable hints

SCALAR_TYPES = {1: ("f32", "<f4", 4), 2: ("f16", "<f2", 2)}
SCALAR_CPCA = 3  # §3.4: a BLKT record whose block is a CPCA section (§3.13)
CPCA_HEADER = 32
ENV_PRECISIONS = {1: ("f32", "<f4", 4), 3: ("f64", "<f8", 8)}
KIND_NAMES = {
    1: "unshadowed-diffuse",
    2: "shadowed-diffuse",
    3: "visibility",
    4: "interreflected-diffuse",
}
LOBE_NAMES = {1: "clamped-cosine", 2: "phong"}
SAMPLE_KINDS = {1: "vertex", 2: "pixel", 3: "texel"}

TAGS_ONCE = (b"BINF", b"STRS", b"OBJT", b"BLKT", b"META")  # required, exactly once
TAGS_OPTIONAL = (b"ENVL", b"BRDF", b"GLSY", b"RFLD")  # at most once
TAGS_MANY = (b"XFER", b"CPCA", b"MESH", b"CVRG")  # found through BLKT / OBJT
KNOWN_TAGS = set(TAGS_ONCE) | set(TAGS_OPTIONAL) | set(TAGS_MANY)

# Minimum record sizes of the table sections (§3); later minors may append fields.
OBJT_RECORD_10 = 56
OBJT_RECORD_11 = 64
BLKT_RECORD = 48
BRDF_RECORD = 32
GLSY_RECORD = 40
BINF_SIZE = 40

# RFLD (§3.14): a sampled reflectance field
RFLD_HEADER = 32
RFLD_CHANNELS = 3
RFLD_MAX_DIRECTIONS = 2**24
# Elements checked at a time for finiteness / sign (bounds the temporary arrays of a big field)
FIELD_CHUNK = 1 << 22

SH_FIXED = {
    "basis": "real-orthonormal",
    "phase": "condon-shortley",
    "index_order": "l(l+1)+m",
    "angles": "theta-from-+Z, phi=atan2(y,x)",
    "order": "band-count",
}

# Tolerance for "unit shading normal, length 1 within f32 rounding" (§3.10).
NORMAL_TOLERANCE = 1e-5


class PrtbError(Exception):
    """A violation of SPEC.md: the message is the one line printed after `FILE: `."""


def fail(message: str) -> None:
    raise PrtbError(message)


# --------------------------------------------------------------------------------------------
# Small helpers
# --------------------------------------------------------------------------------------------


def fnv1a64(*chunks) -> int:
    """FNV-1a 64 (§5) over the concatenation of the byte chunks."""
    h = 0xCBF29CE484222325
    prime = 0x100000001B3
    mask = 0xFFFFFFFFFFFFFFFF
    for chunk in chunks:
        for b in bytes(chunk):
            h = ((h ^ b) * prime) & mask
    return h


def tag_text(tag: bytes) -> str:
    return "".join(chr(b) if 0x20 <= b < 0x7F else "\\x%02x" % b for b in tag)


def short(value, limit: int = 60) -> str:
    text = json.dumps(value) if not isinstance(value, (bytes, memoryview)) else repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def is_number(v) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)
            and (not isinstance(v, float) or math.isfinite(v)))


class Section:
    __slots__ = ("index", "tag", "flags", "offset", "length", "crc", "payload")

    def __init__(self, index, tag, flags, offset, length, crc):
        self.index = index
        self.tag = tag
        self.flags = flags
        self.offset = offset
        self.length = length
        self.crc = crc
        self.payload = None  # memoryview, set once bounds are checked

    def __str__(self):
        return "section %d (%s)" % (self.index, tag_text(self.tag))


class Obj:
    """One OBJT record plus what it references."""

    def __init__(self, **kw):
        self.__dict__.update(kw)
        self.blocks = []
        self.mesh = None
        self.coverage = None
        self.atlas_uvs = None


class Bake:
    """The parsed, validated file."""

    def __init__(self):
        self.major = self.minor = 0
        self.scalar_type = 1
        self.sections = []
        self.binf = {}
        self.objects = []
        self.blocks = []
        self.env = None
        self.brdfs = []
        self.glossy = []
        self.meta = None
        self.field = None  # RFLD (§3.14): dict, see rfld_structure()


# --------------------------------------------------------------------------------------------
# Parsing and validation (§4 order)
# --------------------------------------------------------------------------------------------


def parse(data: bytes) -> Bake:
    """Parse and validate `data` (the whole file). Raises PrtbError on any violation."""
    bake = Bake()
    mv = memoryview(data)
    n = len(data)

    # ---- §4.1 magic ------------------------------------------------------------------------
    if n < len(MAGIC):
        if MAGIC.startswith(bytes(data)):
            fail("truncated: %d bytes, shorter than the magic" % n)
        fail("bad magic (not a PRTBAKE file)")
    if bytes(mv[:8]) != MAGIC:
        fail("bad magic (not a PRTBAKE file)")

    # ---- §4.2 header size, major version -----------------------------------------------------
    if n < HEADER_SIZE:
        fail("truncated: %d bytes, shorter than the 64-byte header" % n)
    major, minor, header_size, hflags = struct.unpack_from("<4I", data, 8)
    file_size, table_offset = struct.unpack_from("<QQ", data, 24)
    (section_count, entry_size, alignment, scalar_type, _reserved,
     header_crc) = struct.unpack_from("<6I", data, 40)
    if major != KNOWN_MAJOR:
        fail("unsupported version %d.%d (this reader knows major version %d)"
             % (major, minor, KNOWN_MAJOR))
    bake.major, bake.minor = major, minor

    # ---- §4.3 file_size ------------------------------------------------------------------------
    if file_size > n:
        fail("truncated: header says file_size %d, file has %d bytes" % (file_size, n))
    if file_size < n:
        fail("trailing bytes: header says file_size %d, file has %d bytes" % (file_size, n))

    # ---- §4.4 section table bounds, header CRC ---------------------------------------------------
    table_len = ENTRY_SIZE * section_count
    if table_offset < HEADER_SIZE or table_offset % 8 or table_offset + table_len > n:
        fail("section table out of bounds (offset %d, %d entries, file %d bytes)"
             % (table_offset, section_count, n))
    crc = zlib.crc32(mv[table_offset:table_offset + table_len], zlib.crc32(mv[0:60]))
    if crc != header_crc:
        fail("header checksum mismatch (stored 0x%08x, computed 0x%08x)" % (header_crc, crc))

    # ---- §4.5 header fields ------------------------------------------------------------------------
    if header_size != HEADER_SIZE:
        fail("header_size is %d, expected 64" % header_size)
    if entry_size != ENTRY_SIZE:
        fail("section_entry_size is %d, expected 32" % entry_size)
    if not (16 <= alignment <= 4096 and alignment & (alignment - 1) == 0):
        fail("payload_alignment %d is not a power of two in 16..4096" % alignment)
    if scalar_type not in SCALAR_TYPES:
        fail("scalar_type %d is not 1 (f32) or 2 (f16)" % scalar_type)
    if hflags & UNDERSTOOD_MASK:
        fail("header flags 0x%08x set bits this reader does not know" % hflags)
    bake.scalar_type = scalar_type

    # ---- §4.6 every section: flags, alignment, bounds, overlap, padding, CRC ----------------------
    sections = []
    for i in range(section_count):
        tag, flags, offset, length, scrc, _res = struct.unpack_from(
            "<4sIQQII", data, table_offset + ENTRY_SIZE * i)
        sections.append(Section(i, tag, flags, offset, length, scrc))
    for s in sections:
        unknown = s.flags & UNDERSTOOD_MASK & ~FLAG_REQUIRED
        if unknown:
            fail("%s: flags 0x%08x set bits this reader does not know" % (s, s.flags))
        if s.offset % alignment:
            fail("%s: offset %d is not a multiple of payload_alignment %d"
                 % (s, s.offset, alignment))
        if s.offset > file_size or s.length > file_size - s.offset:
            fail("%s: payload [%d, +%d) runs past the end of the file (%d bytes)"
                 % (s, s.offset, s.length, file_size))
    regions = [(0, HEADER_SIZE, "the header")]
    if table_len:
        regions.append((table_offset, table_offset + table_len, "the section table"))
    for s in sections:
        if s.length:  # an empty payload occupies no byte and so overlaps nothing
            regions.append((s.offset, s.offset + s.length, str(s)))
    regions.sort(key=lambda r: (r[0], r[1]))
    for a, b in zip(regions, regions[1:]):
        if b[0] < a[1]:
            fail("%s overlaps %s" % (b[2], a[2]))
    cursor = 0
    for start, end, _name in regions + [(n, n, "end of file")]:
        if start > cursor and data.count(0, cursor, start) != start - cursor:
            pos = next(k for k in range(cursor, start) if data[k])
            fail("padding byte at offset %d is 0x%02x, not zero" % (pos, data[pos]))
        cursor = max(cursor, end)
    for s in sections:
        s.payload = mv[s.offset:s.offset + s.length]
        c = zlib.crc32(s.payload)
        if c != s.crc:
            fail("%s: checksum mismatch (stored 0x%08x, computed 0x%08x)" % (s, s.crc, c))
    bake.sections = sections

    # ---- §4.7 required / optional / unknown tags -------------------------------------------------
    by_tag = {}
    for s in sections:
        if s.tag in KNOWN_TAGS:
            by_tag.setdefault(s.tag, []).append(s)
        elif s.flags & FLAG_REQUIRED:
            fail("%s: unknown section tag with the REQUIRED flag" % s)
        # unknown, not required: skipped
    for tag in TAGS_ONCE:
        found = by_tag.get(tag, [])
        if not found:
            fail("required section %s missing" % tag_text(tag))
        if len(found) > 1:
            fail("section %s present %d times (must be once)" % (tag_text(tag), len(found)))
    for tag in TAGS_OPTIONAL:
        if len(by_tag.get(tag, [])) > 1:
            fail("section %s present %d times (at most once)"
                 % (tag_text(tag), len(by_tag[tag])))
    one = {tag: by_tag[tag][0] for tag in TAGS_ONCE}
    opt = {tag: by_tag[tag][0] for tag in TAGS_OPTIONAL if tag in by_tag}

    # ---- §4.8 table lengths, checked before use ----------------------------------------------------
    binf = one[b"BINF"]
    if binf.length < BINF_SIZE:
        fail("BINF: length %d, shorter than %d" % (binf.length, BINF_SIZE))
    objt_min = OBJT_RECORD_10 if minor == 0 else OBJT_RECORD_11
    objt_count, objt_rs = table_header(one[b"OBJT"], "OBJT", objt_min)
    blkt_count, blkt_rs = table_header(one[b"BLKT"], "BLKT", BLKT_RECORD)
    brdf_count = brdf_rs = glsy_count = glsy_rs = 0
    if b"BRDF" in opt:
        brdf_count, brdf_rs = table_header(opt[b"BRDF"], "BRDF", BRDF_RECORD)
    if b"GLSY" in opt:
        glsy_count, glsy_rs = table_header(opt[b"GLSY"], "GLSY", GLSY_RECORD)
    if b"ENVL" in opt:
        envl = opt[b"ENVL"]
        if envl.length < 16:
            fail("ENVL: length %d, shorter than its 16-byte header" % envl.length)
        env_order, env_channels, env_precision, _r = struct.unpack_from("<4I", envl.payload, 0)
        if not 1 <= env_order <= 65535:
            fail("ENVL: order %d not in 1..65535" % env_order)
        if env_channels != 3:
            fail("ENVL: channels %d, expected 3" % env_channels)
        if env_precision not in ENV_PRECISIONS:
            fail("ENVL: precision %d is not 1 (f32) or 3 (f64)" % env_precision)
        pname, pdtype, psize = ENV_PRECISIONS[env_precision]
        expect = 16 + 3 * env_order * env_order * psize
        if envl.length != expect:
            fail("ENVL: length %d, expected 16 + 3n²×%d = %d" % (envl.length, psize, expect))
        bake.env = {
            "order": env_order,
            "precision": pname,
            "values": np.frombuffer(envl.payload, dtype=pdtype, offset=16),
            "section": envl.index,
        }

    # ---- §4.9 cross references and counts of §3 ------------------------------------------------------
    # BINF (§3.1)
    (sample_kind, bounces, width, height, rays, shard_index, shard_count, _r,
     seed) = struct.unpack_from("<8IQ", binf.payload, 0)
    if sample_kind not in SAMPLE_KINDS:
        fail("BINF: sample_kind %d is not 1 (per-vertex), 2 (per-pixel) or 3 (per-texel)"
             % sample_kind)
    if sample_kind == 2 and (width < 1 or height < 1):
        fail("BINF: per-pixel bake with image size %dx%d" % (width, height))
    if sample_kind == 3 and (width < 1 or height < 1):
        fail("BINF: per-texel bake with lightmap size %dx%d" % (width, height))
    if sample_kind == 1 and (width != 0 or height != 0):
        fail("BINF: per-vertex bake with image size %dx%d (must be 0x0)" % (width, height))
    if not shard_index < shard_count:
        fail("BINF: shard_index %d not below shard_count %d" % (shard_index, shard_count))
    per_pixel = sample_kind == 2
    per_texel = sample_kind == 3  # §3.1: lightmapped objects (with a CVRG) and per-vertex ones
    bake.binf = dict(sample_kind=sample_kind, bounces=bounces, width=width, height=height,
                     rays_per_point=rays, shard_index=shard_index, shard_count=shard_count,
                     seed=seed)

    strs = one[b"STRS"].payload

    def string(offset, length, what):
        if offset + length > len(strs):
            fail("%s: string reference (%d, %d) outside the %d-byte STRS pool"
                 % (what, offset, length, len(strs)))
        try:
            return bytes(strs[offset:offset + length]).decode("utf-8")
        except UnicodeDecodeError:
            fail("%s: string (%d, %d) is not valid UTF-8" % (what, offset, length))

    def section_ref(index, tag, what):
        if index >= len(sections):
            fail("%s: section index %d out of range (%d sections)" % (what, index, len(sections)))
        s = sections[index]
        if s.tag != tag:
            fail("%s: section %d has tag %s, expected %s"
                 % (what, index, tag_text(s.tag), tag_text(tag)))
        return s

    # OBJT (§3.3)
    objt = one[b"OBJT"].payload
    names = set()
    mesh_owner = {}
    cov_owner = {}
    block_cursor = 0
    for o in range(objt_count):
        base = 16 + o * objt_rs
        (name_off, name_len, ghash, point_count, point_first, points_in_file, order,
         channels, first_block, block_count) = struct.unpack_from("<IIQQQQIIII", objt, base)
        mesh_index = cov_index = NONE_INDEX
        if objt_rs >= OBJT_RECORD_11:
            mesh_index, cov_index = struct.unpack_from("<II", objt, base + 56)
        what = "OBJT record %d" % o
        name = string(name_off, name_len, what)
        if not name:
            fail("%s: empty object name" % what)
        if name in names:
            fail("%s: duplicate object name %s" % (what, short(name)))
        names.add(name)
        what = "object %d (%s)" % (o, short(name))
        if point_first + points_in_file > point_count:
            fail("%s: point_first %d + points_in_file %d > point_count %d"
                 % (what, point_first, points_in_file, point_count))
        if not 1 <= order <= 65535:
            fail("%s: order %d not in 1..65535" % (what, order))
        if channels not in (1, 3):
            fail("%s: channels %d is not 1 or 3" % (what, channels))
        if first_block != block_cursor:
            fail("%s: first_block %d, expected %d (block runs must be consecutive)"
                 % (what, first_block, block_cursor))
        if block_count > blkt_count - block_cursor:
            fail("%s: blocks [%d, +%d) run past the %d BLKT records"
                 % (what, first_block, block_count, blkt_count))
        block_cursor += block_count
        if per_pixel and point_count != width * height:
            fail("%s: point_count %d != image %dx%d" % (what, point_count, width, height))
        if mesh_index != NONE_INDEX:
            section_ref(mesh_index, b"MESH", what + " mesh_section")
            if mesh_index in mesh_owner:
                fail("%s: MESH section %d already referenced by object %d"
                     % (what, mesh_index, mesh_owner[mesh_index]))
            mesh_owner[mesh_index] = o
        if cov_index != NONE_INDEX:
            section_ref(cov_index, b"CVRG", what + " coverage_section")
            if sample_kind == 1:
                fail("%s: coverage section in a per-vertex bake" % what)
            if cov_index in cov_owner:
                fail("%s: CVRG section %d already referenced by object %d"
                     % (what, cov_index, cov_owner[cov_index]))
            cov_owner[cov_index] = o
            # §3.1, §4.9: a lightmapped object of a per-texel bake has one point per texel
            if per_texel and point_count != width * height:
                fail("%s: lightmapped object (with a CVRG) has point_count %d != lightmap "
                     "%dx%d of a per-texel bake" % (what, point_count, width, height))
        bake.objects.append(Obj(index=o, name=name, geometry_hash=ghash,
                                point_count=point_count, point_first=point_first,
                                points_in_file=points_in_file, order=order, channels=channels,
                                first_block=first_block, block_count=block_count,
                                mesh_section=mesh_index, coverage_section=cov_index))
    if block_cursor != blkt_count:
        fail("OBJT: the objects' block runs cover %d of the %d BLKT records"
             % (block_cursor, blkt_count))
    for s in by_tag.get(b"MESH", []):
        if s.index not in mesh_owner:
            fail("%s is referenced by no object" % s)
    for s in by_tag.get(b"CVRG", []):
        if s.index not in cov_owner:
            fail("%s is referenced by no object" % s)

    # BLKT (§3.4), XFER lengths (§3.5), CPCA structure (§3.13)
    blkt = one[b"BLKT"].payload
    _sname, sdtype, ssize = SCALAR_TYPES[scalar_type]
    xfer_user = {}  # XFER and CPCA section index -> the BLKT record using it
    for obj in bake.objects:
        kinds_seen = set()
        for b in range(obj.first_block, obj.first_block + obj.block_count):
            base = 16 + b * blkt_rs
            (object_index, kind, bbounces, bchannels, border, bscalar, bpoints, section_index,
             _res, data_length) = struct.unpack_from("<6IQIIQ", blkt, base)
            what = "BLKT record %d" % b
            if object_index != obj.index:
                fail("%s: object_index %d, but it lies in object %d's run"
                     % (what, object_index, obj.index))
            if kind not in KIND_NAMES:
                fail("%s: unknown transfer kind %d" % (what, kind))
            if kind == 4:
                if not 1 <= bbounces <= bounces:
                    fail("%s: interreflected-diffuse with bounces %d, not in 1..%d (BINF)"
                         % (what, bbounces, bounces))
            elif bbounces != 0:
                fail("%s: kind %s with bounces %d (must be 0)"
                     % (what, KIND_NAMES[kind], bbounces))
            key = (kind, bbounces)
            if key in kinds_seen:
                fail("%s: object %d has kind %s%s twice" % (
                    what, obj.index, KIND_NAMES[kind],
                    " (bounces %d)" % bbounces if kind == 4 else ""))
            kinds_seen.add(key)
            if bchannels != obj.channels:
                fail("%s: channels %d != object's %d" % (what, bchannels, obj.channels))
            if border != obj.order:
                fail("%s: order %d != object's %d" % (what, border, obj.order))
            if bscalar != scalar_type and bscalar != SCALAR_CPCA:
                fail("%s: scalar_type %d is neither the header's %d nor 3 (CPCA)"
                     % (what, bscalar, scalar_type))
            if bpoints != obj.points_in_file:
                fail("%s: point_count %d != object's points_in_file %d"
                     % (what, bpoints, obj.points_in_file))
            if bscalar == SCALAR_CPCA:
                cs = section_ref(section_index, b"CPCA", what)
                if section_index in xfer_user:
                    fail("%s: CPCA section %d already used by BLKT record %d"
                         % (what, section_index, xfer_user[section_index]))
                xfer_user[section_index] = b
                if data_length != cs.length:
                    fail("%s: data_length %d != length %d of %s (a CPCA block)"
                         % (what, data_length, cs.length, cs))
                cpca = cpca_structure(cs, obj, "%s %s" % (what, cs))
                block = dict(index=b, object_index=object_index, kind=kind, bounces=bbounces,
                             section=section_index, data=None, dtype=None, cpca=cpca)
                obj.blocks.append(block)
                bake.blocks.append(block)
                continue
            xs = section_ref(section_index, b"XFER", what)
            if section_index in xfer_user:
                fail("%s: XFER section %d already used by BLKT record %d"
                     % (what, section_index, xfer_user[section_index]))
            xfer_user[section_index] = b
            expect = bpoints * bchannels * border * border * ssize
            if data_length != expect:
                fail("%s: data_length %d != points×channels×order²×%d = %d"
                     % (what, data_length, ssize, expect))
            if xs.length != data_length:
                fail("%s: data_length %d != length %d of %s" % (what, data_length, xs.length, xs))
            block = dict(index=b, object_index=object_index, kind=kind, bounces=bbounces,
                         section=section_index, data=xs.payload, dtype=sdtype, cpca=None)
            obj.blocks.append(block)
            bake.blocks.append(block)
    for s in by_tag.get(b"XFER", []) + by_tag.get(b"CPCA", []):
        if s.index not in xfer_user:
            fail("%s is used by no BLKT record" % s)

    # BRDF (§3.7)
    if b"BRDF" in opt:
        payload = opt[b"BRDF"].payload
        cursor = 16 + brdf_count * brdf_rs
        materials = set()
        for k in range(brdf_count):
            mo, ml, lobe, order, exponent, values_offset = struct.unpack_from(
                "<IIIIdQ", payload, 16 + k * brdf_rs)
            what = "BRDF record %d" % k
            material = string(mo, ml, what)
            if not material:
                fail("%s: empty material name" % what)
            if material in materials:
                fail("%s: duplicate material %s" % (what, short(material)))
            materials.add(material)
            if lobe not in LOBE_NAMES:
                fail("%s: unknown lobe %d" % (what, lobe))
            if not math.isfinite(exponent):
                fail("%s: exponent is not finite" % what)
            if lobe == 1 and exponent != 0.0:
                fail("%s: clamped-cosine lobe with exponent %r (must be 0)" % (what, exponent))
            if lobe == 2 and not exponent >= 0.0:
                fail("%s: phong exponent %r < 0" % (what, exponent))
            if order > 65535:
                fail("%s: order %d > 65535" % (what, order))
            if values_offset != cursor:
                fail("%s: values_offset %d, expected %d (packed arrays)"
                     % (what, values_offset, cursor))
            end = cursor + 8 * order
            if end > len(payload):
                fail("%s: values [%d, %d) run past the section (%d bytes)"
                     % (what, cursor, end, len(payload)))
            bake.brdfs.append(dict(material=material, lobe=lobe, order=order,
                                   exponent=exponent,
                                   values=np.frombuffer(payload[cursor:end], dtype="<f8")))
            cursor = end
        if cursor != len(payload):
            fail("BRDF: section is %d bytes, its arrays end at %d" % (len(payload), cursor))

    # GLSY (§3.8)
    if b"GLSY" in opt:
        payload = opt[b"GLSY"].payload
        cursor = 16 + glsy_count * glsy_rs
        materials = set()
        for k in range(glsy_count):
            mo, ml, count_e, order, eo, vo, ro = struct.unpack_from(
                "<IIIIQQQ", payload, 16 + k * glsy_rs)
            what = "GLSY record %d" % k
            material = string(mo, ml, what)
            if material in materials:
                fail("%s: duplicate material %s" % (what, short(material)))
            materials.add(material)
            if count_e < 1:
                fail("%s: elevation_count is 0" % what)
            if not 1 <= order <= 65535:
                fail("%s: order %d not in 1..65535" % (what, order))
            arrays = {}
            for label, offset, count in (("elevations", eo, count_e),
                                         ("values", vo, count_e * order * order),
                                         ("errors", ro, order)):
                if offset != cursor:
                    fail("%s: %s_offset %d, expected %d (packed arrays)"
                         % (what, label, offset, cursor))
                end = cursor + 8 * count
                if end > len(payload):
                    fail("%s: %s [%d, %d) run past the section (%d bytes)"
                         % (what, label, cursor, end, len(payload)))
                arrays[label] = (payload[cursor:end], np.frombuffer(payload[cursor:end], "<f8"))
                cursor = end
            bake.glossy.append(dict(material=material, order=order, elevation_count=count_e,
                                    elevations=arrays["elevations"][1],
                                    values_raw=arrays["values"][0],
                                    values=arrays["values"][1], errors=arrays["errors"][1]))
        if cursor != len(payload):
            fail("GLSY: section is %d bytes, its arrays end at %d" % (len(payload), cursor))

    # MESH (§3.10) structure
    for obj in bake.objects:
        if obj.mesh_section == NONE_INDEX:
            continue
        s = sections[obj.mesh_section]
        what = "object %d (%s) MESH %s" % (obj.index, short(obj.name), s)
        if s.length < 16:
            fail("%s: length %d, shorter than its 16-byte header" % (what, s.length))
        object_index, V, T, _r = struct.unpack_from("<4I", s.payload, 0)
        if object_index != obj.index:
            fail("%s: object_index %d != %d" % (what, object_index, obj.index))
        expect = 16 + 24 * V + 12 * T
        if s.length != expect:
            fail("%s: length %d != 16 + 24V + 12T = %d (V=%d, T=%d)"
                 % (what, s.length, expect, V, T))
        # §3.10, §4.9: V = point_count for per-vertex bakes and for the objects without a
        # CVRG of a per-texel bake (which are baked per vertex)
        if sample_kind == 1 and V != obj.point_count:
            fail("%s: vertex_count %d != point_count %d of a per-vertex bake"
                 % (what, V, obj.point_count))
        if per_texel and obj.coverage_section == NONE_INDEX and V != obj.point_count:
            fail("%s: vertex_count %d != point_count %d of an object baked per vertex "
                 "(no CVRG) in a per-texel bake" % (what, V, obj.point_count))
        p = s.payload
        triangles = np.frombuffer(p[16 + 24 * V:expect], dtype="<u4")
        if T and int(triangles.max()) >= V:
            bad = int(np.argmax(triangles >= V))
            fail("%s: triangle %d corner %d has vertex index %d >= V=%d"
                 % (what, bad // 3, bad % 3, int(triangles[bad]), V))
        obj.mesh = dict(section=s.index, V=V, T=T,
                        positions_raw=p[16:16 + 12 * V], normals_raw=p[16 + 12 * V:16 + 24 * V],
                        triangles_raw=p[16 + 24 * V:expect])

    # CVRG (§3.11) structure, hits <= K, per-pixel sums <= K (per-texel: K = 1, no sums)
    covered = []
    common_k = None
    for obj in bake.objects:
        if obj.coverage_section == NONE_INDEX:
            continue
        s = sections[obj.coverage_section]
        what = "object %d (%s) CVRG %s" % (obj.index, short(obj.name), s)
        if s.length < 16:
            fail("%s: length %d, shorter than its 16-byte header" % (what, s.length))
        object_index, K, cpoints = struct.unpack_from("<IIQ", s.payload, 0)
        if object_index != obj.index:
            fail("%s: object_index %d != %d" % (what, object_index, obj.index))
        if K < 1:
            fail("%s: pixel_samples is 0" % what)
        if per_texel and K != 1:
            fail("%s: pixel_samples %d in a per-texel bake (must be 1)" % (what, K))
        if cpoints != obj.points_in_file:
            fail("%s: point_count %d != object's points_in_file %d"
                 % (what, cpoints, obj.points_in_file))
        if s.length != 16 + 4 * cpoints:
            fail("%s: length %d != 16 + 4×point_count = %d" % (what, s.length, 16 + 4 * cpoints))
        if common_k is not None and K != common_k:
            fail("%s: pixel_samples %d differs from another CVRG's %d" % (what, K, common_k))
        common_k = K
        hits = np.frombuffer(s.payload, dtype="<u4", offset=16)
        if hits.size and int(hits.max()) > K:
            bad = int(np.argmax(hits > K))
            fail("%s: hits[%d] = %d > pixel_samples %d" % (what, bad, int(hits[bad]), K))
        obj.coverage = dict(section=s.index, K=K, hits=hits)
        covered.append(obj)
    if covered and per_pixel:  # §3.11: each lightmap is its own image, so not per-texel
        check_pixel_sums(covered, common_k)

    # RFLD (§3.14): header, counts and exact length before anything is viewed; pixel indices
    if b"RFLD" in opt:
        bake.field = rfld_structure(bake, opt[b"RFLD"], objt_count)

    # ---- §4.10 finite values, recomputed geometry hashes -----------------------------------------
    for obj in bake.objects:
        for block in obj.blocks:
            if block["cpca"] is None:
                values = np.frombuffer(block["data"], dtype=sdtype)
                check_finite(values, "XFER %s of BLKT record %d (object %d)"
                             % (sections[block["section"]], block["index"], obj.index))
            else:
                values = cpca_reconstruct(block["cpca"], "CPCA %s of BLKT record %d (object %d)"
                                          % (sections[block["section"]], block["index"],
                                             obj.index))
            block["values"] = values
    if bake.env is not None:
        check_finite(bake.env["values"], "ENVL values")
    if bake.field is not None:
        check_field_values(bake.field)
    for k, brdf in enumerate(bake.brdfs):
        check_finite(brdf["values"], "BRDF record %d values" % k)
    for k, g in enumerate(bake.glossy):
        for label in ("elevations", "values", "errors"):
            check_finite(g[label], "GLSY record %d %s" % (k, label))
    for obj in bake.objects:
        if obj.mesh is None:
            continue
        m = obj.mesh
        what = "object %d (%s) MESH" % (obj.index, short(obj.name))
        positions = np.frombuffer(m["positions_raw"], dtype="<f4")
        normals = np.frombuffer(m["normals_raw"], dtype="<f4")
        check_finite(positions, what + " positions")
        check_finite(normals, what + " normals")
        if m["V"]:
            lengths = np.sqrt((normals.astype(np.float64).reshape(-1, 3) ** 2).sum(axis=1))
            off = np.abs(lengths - 1.0)
            if off.max() > NORMAL_TOLERANCE:
                bad = int(np.argmax(off))
                fail("%s: normal of vertex %d has length %r, not 1"
                     % (what, bad, float(lengths[bad])))
        h = fnv1a64(m["positions_raw"], m["triangles_raw"])
        m["hash"] = h
        if h != obj.geometry_hash:
            fail("%s: recomputed geometry hash 0x%016x != OBJT geometry_hash 0x%016x"
                 % (what, h, obj.geometry_hash))
    for obj in covered:
        # §3.11: an object's transfer is zero in every pixel (per-texel bakes: texel of its
        # lightmap, §3.1) where its hits is 0 — for every XFER block; a CPCA block only
        # approximates it (§3.13), so its reconstruction is exempt.
        hits = obj.coverage["hits"]
        empty = hits == 0
        if not empty.any():
            continue
        width_per_point = obj.channels * obj.order * obj.order
        for block in obj.blocks:
            if block["cpca"] is not None:
                continue
            values = block["values"].reshape(-1, width_per_point)
            nonzero = (values[empty] != 0).any(axis=1)
            if nonzero.any():
                bad = int(np.flatnonzero(empty)[int(np.argmax(nonzero))])
                fail("object %d (%s): %s transfer is non-zero at point %d (%s %d) "
                     "whose coverage hits are 0" % (
                         obj.index, short(obj.name), KIND_NAMES[block["kind"]], bad,
                         "texel" if per_texel else "pixel", obj.point_first + bad))

    # ---- §4.11 metadata JSON ------------------------------------------------------------------------
    bake.meta = check_meta(bake, one[b"META"].payload)
    return bake


def table_header(section: Section, name: str, min_record: int):
    """§3 table header + §4.8: returns (record_count, record_size)."""
    if section.length < 16:
        fail("%s: length %d, shorter than its 16-byte table header" % (name, section.length))
    count, record_size = struct.unpack_from("<II", section.payload, 0)
    if record_size < min_record:
        fail("%s: record_size %d < %d" % (name, record_size, min_record))
    if 16 + count * record_size > section.length:
        fail("%s: %d records of %d bytes do not fit in %d bytes"
             % (name, count, record_size, section.length))
    return count, record_size


def cpca_structure(s: Section, obj: Obj, what: str) -> dict:
    """§3.13 header, counts, exact length and cluster ids of a CPCA section (§4.8, §4.9).

    Every count is checked against the section length before it is used to slice anything;
    the values are left for the §4.10 finiteness check and the reconstruction."""
    if s.length < CPCA_HEADER:
        fail("%s: length %d, shorter than its %d-byte header" % (what, s.length, CPCA_HEADER))
    p = s.payload
    object_index, K, M, D, P = struct.unpack_from("<4IQ", p, 0)
    (rel_error,) = struct.unpack_from("<d", p, 24)
    if object_index != obj.index:
        fail("%s: object_index %d != %d (the block's object)" % (what, object_index, obj.index))
    if K < 1:
        fail("%s: clusters K is 0" % what)
    expect_d = obj.channels * obj.order * obj.order
    if D != expect_d:
        fail("%s: dimension D %d != channels×order² = %d" % (what, D, expect_d))
    if P != obj.points_in_file:
        fail("%s: points P %d != object's points_in_file %d" % (what, P, obj.points_in_file))
    n_clusters = K * (M + 1) * D
    expect = CPCA_HEADER + 4 * n_clusters + 4 * P + 4 * P * M  # Python ints: no overflow
    if s.length != expect:
        fail("%s: length %d != 32 + 4·K·(M+1)·D + 4·P + 4·P·M = %d (K=%d, M=%d, D=%d, P=%d)"
             % (what, s.length, expect, K, M, D, P))
    a = CPCA_HEADER
    b = a + 4 * n_clusters
    c = b + 4 * P
    ids = np.frombuffer(p[b:c], dtype="<u4")
    if P and int(ids.max()) >= K:
        bad = int(np.argmax(ids >= K))
        fail("%s: point %d is in cluster %d >= K=%d" % (what, bad, int(ids[bad]), K))
    return dict(section=s.index, K=K, M=M, D=D, P=P, rel_error=rel_error,
                clusters_raw=p[a:b], ids=ids, weights_raw=p[c:expect])


def cpca_reconstruct(cpca: dict, what: str) -> np.ndarray:
    """§4.10 finiteness of a CPCA section, then t̃ per §3.13, flat [point][channel][coeff].

    In f32 throughout: t = mean (a copy), then for j = 0 … M−1, t = t + (w_j · basis_j), each
    product and each sum rounded to f32 (numpy float32 arithmetic; nothing in f64, no FMA)."""
    K, M, D, P = cpca["K"], cpca["M"], cpca["D"], cpca["P"]
    if not math.isfinite(cpca["rel_error"]):
        fail("%s: rel_error is not finite (%r)" % (what, cpca["rel_error"]))
    clusters = np.frombuffer(cpca["clusters_raw"], dtype="<f4")
    check_finite(clusters, what + " cluster means/basis vectors")
    weights = np.frombuffer(cpca["weights_raw"], dtype="<f4")
    check_finite(weights, what + " weights")
    clusters = clusters.astype(np.float32).reshape(K, M + 1, D)
    weights = weights.astype(np.float32).reshape(P, M)
    ids = cpca["ids"].astype(np.intp)
    with np.errstate(all="ignore"):  # an overflow to ±inf is refused below, not warned about
        t = clusters[ids, 0, :]  # fancy indexing: a float32 copy of each point's mean
        for j in range(M):
            t = t + weights[:, j:j + 1] * clusters[ids, j + 1, :]
    assert t.dtype == np.float32
    t = t.reshape(-1)
    # §3.5/§4.10: the reconstruction is used as an XFER block's data, whose scalars are finite.
    check_finite(t, what + " reconstructed transfer")
    return t


def rfld_structure(bake: Bake, s: Section, objt_count: int) -> dict:
    """§3.14 `RFLD` (with §3.1, §4.8, §4.9): where a field may be, its header, its exact
    length (checked before anything is viewed or allocated) and its pixel indices. The values
    are left for check_field_values() (§4.10)."""
    what = "%s" % s
    binf = bake.binf
    # §3 table: `REQUIRED` (a reader that does not know RFLD must refuse the file, not skip a
    # field and read an empty per-pixel bake); §3.14 is a 1.1 section
    if not s.flags & FLAG_REQUIRED:
        fail("%s: the REQUIRED flag is not set (§3: RFLD is REQUIRED)" % what)
    if bake.minor < 1:
        fail("%s: a reflectance field in a %d.%d file (RFLD is a 1.1 section)"
             % (what, bake.major, bake.minor))
    # §3.14: per-pixel files only (sample_kind 2, the JSON camera)
    if binf["sample_kind"] != 2:
        fail("%s: a reflectance field in a per-%s file (per-pixel files only)"
             % (what, SAMPLE_KINDS[binf["sample_kind"]]))
    # §3.14: a file with RFLD has no objects
    if objt_count:
        fail("%s: a file with a reflectance field has %d objects (OBJT must have 0 records)"
             % (what, objt_count))
    # §3.14 says nothing of shards; prt neither shards nor merges fields: one shard only
    if binf["shard_count"] != 1:
        fail("%s: a reflectance field in shard %d of %d (fields are not sharded)"
             % (what, binf["shard_index"], binf["shard_count"]))
    if s.length < RFLD_HEADER:
        fail("%s: length %d, shorter than its %d-byte header" % (what, s.length, RFLD_HEADER))
    p = s.payload
    W, H, channels, _r0, P, _r1 = struct.unpack_from("<4IQQ", p, 0)
    if W < 2:
        fail("%s: W = %d directions per row (must be >= 2)" % (what, W))
    if H < 1:
        fail("%s: H = %d rows (must be >= 1)" % (what, H))
    if W * H > RFLD_MAX_DIRECTIONS:
        fail("%s: W×H = %d×%d = %d directions > 2^24" % (what, W, H, W * H))
    if channels != RFLD_CHANNELS:
        fail("%s: channels %d (must be 3)" % (what, channels))
    image = binf["width"] * binf["height"]
    if P > image:  # strictly increasing indices below W×H: at most W×H of them
        fail("%s: P = %d pixels held, more than the %dx%d image has"
             % (what, P, binf["width"], binf["height"]))
    _sname, sdtype, ssize = SCALAR_TYPES[bake.scalar_type]
    count = RFLD_CHANNELS * W * H * P
    expect = RFLD_HEADER + 4 * P + ssize * count  # Python ints: no overflow
    if s.length != expect:
        fail("%s: length %d != 32 + 4P + %d·3WHP = %d (W=%d, H=%d, P=%d)"
             % (what, s.length, ssize, expect, W, H, P))
    pixels = np.frombuffer(p[RFLD_HEADER:RFLD_HEADER + 4 * P], dtype="<u4")
    if P:
        steps = np.diff(pixels.astype(np.int64))
        if steps.size and not (steps > 0).all():
            k = int(np.argmax(steps <= 0)) + 1
            fail("%s: pixel indices not strictly increasing: pixels[%d] = %d after "
                 "pixels[%d] = %d" % (what, k, int(pixels[k]), k - 1, int(pixels[k - 1])))
        if int(pixels[-1]) >= image:  # increasing: the last is the largest
            fail("%s: pixels[%d] = %d outside the %dx%d image (>= %d)"
                 % (what, P - 1, int(pixels[-1]), binf["width"], binf["height"], image))
    values = np.frombuffer(p[RFLD_HEADER + 4 * P:expect], dtype=sdtype)
    return dict(section=s.index, W=W, H=H, channels=channels, P=P, pixels=pixels,
                values=values, scalar=SCALAR_TYPES[bake.scalar_type][0])


def check_field_values(field: dict) -> None:
    """§3.14 / §4.10: every value of the field finite and >= 0 (−0.0 compares equal to 0 and
    is accepted), checked in chunks so that a big field needs no full-size temporaries."""
    values = field["values"]
    per_pixel = RFLD_CHANNELS * field["W"] * field["H"]
    directions = field["W"] * field["H"]
    for start in range(0, values.size, FIELD_CHUNK):
        chunk = values[start:start + FIELD_CHUNK]
        bad = ~(np.isfinite(chunk) & (chunk >= 0))
        if bad.any():
            k = start + int(np.argmax(bad))
            v = float(values[k])
            held, rest = divmod(k, per_pixel)
            channel, direction = divmod(rest, directions)
            fail("%s: value %d (pixel %d, channel %d, direction %d) is %s (%r)" % (
                "section %d (RFLD)" % field["section"], k, int(field["pixels"][held]), channel,
                direction, "negative" if math.isfinite(v) else "not finite", v))


def check_finite(values: np.ndarray, what: str) -> None:
    ok = np.isfinite(values)
    if not ok.all():
        bad = int(np.argmin(ok))
        fail("%s: element %d is not finite (%r)" % (what, bad, float(values[bad])))


def check_pixel_sums(covered, K) -> None:
    """§3.11: over all objects the hits of one pixel add up to at most K."""
    ranges = {(o.point_first, o.points_in_file) for o in covered}
    if len(ranges) == 1:
        total = np.zeros(covered[0].points_in_file, dtype=np.uint64)
        for o in covered:
            total += o.coverage["hits"].astype(np.uint64)
        first = covered[0].point_first
        pixels = None
    else:  # objects hold different point ranges (a shard): sum by absolute pixel index
        idx = np.concatenate([np.arange(o.points_in_file, dtype=np.uint64)
                              + np.uint64(o.point_first) for o in covered])
        hits = np.concatenate([o.coverage["hits"].astype(np.int64) for o in covered])
        pixels, inverse = np.unique(idx, return_inverse=True)
        total = np.zeros(pixels.size, dtype=np.int64)
        np.add.at(total, inverse, hits)
        first = 0
    if total.size and int(total.max()) > K:
        bad = int(np.argmax(total > K))
        pixel = first + bad if pixels is None else int(pixels[bad])
        fail("CVRG: hits of pixel %d add up to %d over all objects > pixel_samples %d"
             % (pixel, int(total[bad]), K))


# --------------------------------------------------------------------------------------------
# META JSON (§3.9, §4.11)
# --------------------------------------------------------------------------------------------


def _reject_constant(name):
    raise ValueError("%s is not JSON" % name)


class Meta:
    """Typed access to the META JSON with one-line errors."""

    def field(self, obj, key, where):
        if not isinstance(obj, dict):
            fail("META: %s is not an object" % where)
        if key not in obj:
            fail("META: %s: missing field '%s'" % (where, key))
        return obj[key]

    def typed(self, value, kind, where, lo=None, hi=None):
        ok = True
        if kind == "u32":
            ok = is_int(value) and 0 <= value <= U32_MAX
        elif kind == "u64":
            ok = is_int(value) and 0 <= value <= U64_MAX
        elif kind == "string":
            ok = isinstance(value, str)
        elif kind == "number":
            ok = is_number(value)
        elif kind == "object":
            ok = isinstance(value, dict)
        elif kind == "array":
            ok = isinstance(value, list)
        elif kind == "bool":
            ok = isinstance(value, bool)
        if not ok:
            desc = {"u32": "a u32 integer", "u64": "a u64 integer", "string": "a string",
                    "number": "a finite number", "object": "an object", "array": "an array",
                    "bool": "a boolean"}[kind]
            fail("META: %s must be %s, got %s" % (where, desc, short(value)))
        return value

    def get(self, obj, key, kind, where):
        return self.typed(self.field(obj, key, where), kind, "%s.%s" % (where, key))

    def equal(self, value, expected, where, source):
        if value != expected or type(value) is bool:
            fail("META: %s is %s, but %s says %s" % (where, short(value), source, short(expected)))


def check_meta(bake: Bake, payload) -> dict:
    try:
        text = bytes(payload).decode("utf-8")
    except UnicodeDecodeError as e:
        fail("META: not valid UTF-8 (%s)" % e.reason)
    try:
        meta = json.loads(text, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as e:
        fail("META: not valid JSON (%s)" % str(e).splitlines()[0])
    M = Meta()
    root = "root"
    if not isinstance(meta, dict):
        fail("META: the JSON is not an object")
    binf = bake.binf
    per_pixel = binf["sample_kind"] == 2
    per_texel = binf["sample_kind"] == 3

    # format, format_version
    M.equal(M.get(meta, "format", "string", root), "prt-bake", "format", "§3.9")
    fv = M.get(meta, "format_version", "array", root)
    if len(fv) != 2 or not all(is_int(v) and 0 <= v <= U32_MAX for v in fv):
        fail("META: format_version must be an array of two integers, got %s" % short(fv))
    if fv != [bake.major, bake.minor]:
        fail("META: format_version %s, but the header says [%d, %d]"
             % (short(fv), bake.major, bake.minor))
    # sh, colour_space
    sh = M.get(meta, "sh", "object", root)
    for key, expected in SH_FIXED.items():
        M.equal(M.get(sh, key, "string", "sh"), expected, "sh.%s" % key, "format 1.x")
    M.equal(M.get(meta, "colour_space", "string", root), "linear-rec709", "colour_space",
            "format 1.x")
    M.equal(M.get(meta, "scalar_type", "string", root), SCALAR_TYPES[bake.scalar_type][0],
            "scalar_type", "the header")
    # sample_kind
    sk = M.get(meta, "sample_kind", "object", root)
    kind = M.get(sk, "kind", "string", "sample_kind")
    M.equal(kind, SAMPLE_KINDS[binf["sample_kind"]], "sample_kind.kind", "BINF")
    if per_pixel or per_texel:  # {"kind": "pixel"/"texel", "width": W, "height": H}
        M.equal(M.get(sk, "width", "u32", "sample_kind"), binf["width"], "sample_kind.width",
                "BINF")
        M.equal(M.get(sk, "height", "u32", "sample_kind"), binf["height"],
                "sample_kind.height", "BINF")
    M.equal(M.get(meta, "rays_per_point", "u32", root), binf["rays_per_point"],
            "rays_per_point", "BINF")
    M.equal(M.get(meta, "bounces", "u32", root), binf["bounces"], "bounces", "BINF")
    # seed: decimal string since 1.1; a u64 integer in 1.0 files
    seed = M.field(meta, "seed", root)
    if isinstance(seed, str):
        if not re.fullmatch(r"0|[1-9][0-9]{0,19}", seed) or int(seed) > U64_MAX:
            fail("META: seed %s is not a decimal u64 without sign or leading zeros" % short(seed))
        seed_value = int(seed)
    elif is_int(seed):  # the 1.0 form; readers accept it in any 1.x file (§3.9)
        if not 0 <= seed <= U64_MAX:
            fail("META: seed %s out of the u64 range" % short(seed))
        seed_value = seed
    else:
        fail("META: seed must be a string of decimal digits (or a u64 integer), got %s"
             % short(seed))
    if seed_value != binf["seed"]:
        fail("META: seed %d, but BINF says %d" % (seed_value, binf["seed"]))
    # shard
    shard = M.get(meta, "shard", "object", root)
    M.equal(M.get(shard, "index", "u32", "shard"), binf["shard_index"], "shard.index", "BINF")
    M.equal(M.get(shard, "count", "u32", "shard"), binf["shard_count"], "shard.count", "BINF")
    # tool
    tool = M.get(meta, "tool", "object", root)
    M.get(tool, "name", "string", "tool")
    M.get(tool, "version", "string", "tool")
    # camera (1.1)
    camera = meta.get("camera")
    if camera is not None or (per_pixel and bake.minor >= 1):
        if not per_pixel:
            # §3.9 names null for per-vertex bakes and an object for per-pixel ones; a
            # per-texel bake has no camera image (its points are texels), so null as well.
            fail("META: camera must be null in a per-%s bake, got %s"
                 % (SAMPLE_KINDS[binf["sample_kind"]], short(camera)))
        if camera is None:
            fail("META: a per-pixel %d.%d file must have a camera" % (bake.major, bake.minor))
        M.typed(camera, "object", "camera")
        M.equal(M.get(camera, "model", "string", "camera"), "pinhole", "camera.model", "§3.9")
        for key in ("eye", "target", "up"):
            vec = M.get(camera, key, "array", "camera")
            if len(vec) != 3 or not all(is_number(v) for v in vec):
                fail("META: camera.%s must be an array of three finite numbers, got %s"
                     % (key, short(vec)))
        M.get(camera, "fov_y_degrees", "number", "camera")
        M.equal(M.get(camera, "width", "u32", "camera"), binf["width"], "camera.width", "BINF")
        M.equal(M.get(camera, "height", "u32", "camera"), binf["height"], "camera.height",
                "BINF")
    # settings
    settings = M.get(meta, "settings", "object", root)
    pixel_samples = 1
    if "pixel_samples" in settings:
        pixel_samples = M.typed(settings["pixel_samples"], "u32", "settings.pixel_samples")
        if pixel_samples < 1:
            fail("META: settings.pixel_samples is 0")
    if "albedo_in_transfer" in settings:
        M.typed(settings["albedo_in_transfer"], "bool", "settings.albedo_in_transfer")
    if "target_psnr" in settings:
        M.typed(settings["target_psnr"], "number", "settings.target_psnr")
    if per_texel:
        check_lightmaps(M, bake, settings)
    if bake.field is not None:
        check_reflectance_settings(M, bake, settings)
    elif "reflectance" in settings:
        # §3.14: the key records a field's parameters; without a field it describes nothing
        fail("META: settings.reflectance in a file without a reflectance field (RFLD)")
    # decisions
    decisions = M.get(meta, "decisions", "array", root)
    for k, d in enumerate(decisions):
        where = "decisions[%d]" % k
        M.typed(d, "object", where)
        obj_name = M.field(d, "object", where)
        if obj_name is not None and not isinstance(obj_name, str):
            fail("META: %s.object must be a string or null, got %s" % (where, short(obj_name)))
        M.get(d, "decision", "string", where)
        M.get(d, "reason", "string", where)
    # objects
    objects = M.get(meta, "objects", "array", root)
    if len(objects) != len(bake.objects):
        fail("META: objects has %d entries, OBJT has %d records"
             % (len(objects), len(bake.objects)))
    for obj, j in zip(bake.objects, objects):
        where = "objects[%d]" % obj.index
        M.typed(j, "object", where)
        M.equal(M.get(j, "name", "string", where), obj.name, where + ".name", "OBJT")
        gh = M.get(j, "geometry_hash", "string", where)
        if not re.fullmatch(r"0x[0-9a-f]{16}", gh):
            fail("META: %s.geometry_hash %s is not 0x + 16 lower-case hex digits"
                 % (where, short(gh)))
        if int(gh, 16) != obj.geometry_hash:
            fail("META: %s.geometry_hash %s, but OBJT says 0x%016x"
                 % (where, gh, obj.geometry_hash))
        for key in ("point_count", "point_first", "points_in_file"):
            M.equal(M.get(j, key, "u64", where), getattr(obj, key), "%s.%s" % (where, key),
                    "OBJT")
        for key in ("order", "channels"):
            M.equal(M.get(j, key, "u32", where), getattr(obj, key), "%s.%s" % (where, key),
                    "OBJT")
        blocks = M.get(j, "blocks", "array", where)
        if len(blocks) != len(obj.blocks):
            fail("META: %s.blocks has %d entries, BLKT gives the object %d"
                 % (where, len(blocks), len(obj.blocks)))
        for k, (jb, block) in enumerate(zip(blocks, obj.blocks)):
            w = "%s.blocks[%d]" % (where, k)
            M.typed(jb, "object", w)
            M.equal(M.get(jb, "kind", "string", w), KIND_NAMES[block["kind"]], w + ".kind",
                    "BLKT")
            M.equal(M.get(jb, "bounces", "u32", w), block["bounces"], w + ".bounces", "BLKT")
            M.equal(M.get(jb, "section", "u32", w), block["section"], w + ".section", "BLKT")
        mesh = j.get("mesh")
        if mesh is None:
            if obj.mesh is not None:
                fail("META: %s.mesh is null, but OBJT references MESH section %d"
                     % (where, obj.mesh_section))
        else:
            w = where + ".mesh"
            M.typed(mesh, "object", w)
            if obj.mesh is None:
                fail("META: %s is not null, but OBJT references no MESH section" % w)
            M.equal(M.get(mesh, "section", "u32", w), obj.mesh["section"], w + ".section", "OBJT")
            M.equal(M.get(mesh, "vertices", "u32", w), obj.mesh["V"], w + ".vertices", "MESH")
            M.equal(M.get(mesh, "triangles", "u32", w), obj.mesh["T"], w + ".triangles", "MESH")
        cov = j.get("coverage")
        if cov is None:
            if obj.coverage is not None:
                fail("META: %s.coverage is null, but OBJT references CVRG section %d"
                     % (where, obj.coverage_section))
        else:
            w = where + ".coverage"
            M.typed(cov, "object", w)
            if obj.coverage is None:
                fail("META: %s is not null, but OBJT references no CVRG section" % w)
            M.equal(M.get(cov, "section", "u32", w), obj.coverage["section"], w + ".section",
                    "OBJT")
            M.equal(M.get(cov, "pixel_samples", "u32", w), obj.coverage["K"],
                    w + ".pixel_samples", "CVRG")
        if obj.coverage is not None and obj.coverage["K"] != pixel_samples:
            fail("META: settings.pixel_samples is %d%s, but object %d's CVRG says %d" % (
                pixel_samples, "" if "pixel_samples" in settings else " (absent)",
                obj.index, obj.coverage["K"]))
    # environment
    env = M.field(meta, "environment", root)
    if env is None:
        if bake.env is not None:
            fail("META: environment is null, but the file has an ENVL section")
    else:
        M.typed(env, "object", "environment")
        if bake.env is None:
            fail("META: environment is not null, but the file has no ENVL section")
        M.equal(M.get(env, "order", "u32", "environment"), bake.env["order"],
                "environment.order", "ENVL")
        M.equal(M.get(env, "precision", "string", "environment"), bake.env["precision"],
                "environment.precision", "ENVL")
    # brdfs
    brdfs = M.get(meta, "brdfs", "array", root)
    if len(brdfs) != len(bake.brdfs):
        fail("META: brdfs has %d entries, BRDF has %d records" % (len(brdfs), len(bake.brdfs)))
    for k, (jb, brdf) in enumerate(zip(brdfs, bake.brdfs)):
        w = "brdfs[%d]" % k
        M.typed(jb, "object", w)
        M.equal(M.get(jb, "material", "string", w), brdf["material"], w + ".material", "BRDF")
        M.equal(M.get(jb, "lobe", "string", w), LOBE_NAMES[brdf["lobe"]], w + ".lobe", "BRDF")
        exponent = M.field(jb, "exponent", w)
        if brdf["lobe"] == 1:
            if exponent is not None:
                fail("META: %s.exponent must be null for clamped-cosine, got %s"
                     % (w, short(exponent)))
        else:
            if not is_number(exponent) or exponent < 0:
                fail("META: %s.exponent must be a number >= 0 for phong, got %s"
                     % (w, short(exponent)))
            if exponent != brdf["exponent"]:
                fail("META: %s.exponent %s, but BRDF says %r" % (w, short(exponent),
                                                                brdf["exponent"]))
        M.equal(M.get(jb, "order", "u32", w), brdf["order"], w + ".order", "BRDF")
    # glossy
    glossy = M.get(meta, "glossy", "array", root)
    if len(glossy) != len(bake.glossy):
        fail("META: glossy has %d entries, GLSY has %d records" % (len(glossy), len(bake.glossy)))
    for k, (jg, g) in enumerate(zip(glossy, bake.glossy)):
        w = "glossy[%d]" % k
        M.typed(jg, "object", w)
        M.equal(M.get(jg, "material", "string", w), g["material"], w + ".material", "GLSY")
        M.equal(M.get(jg, "elevations", "u32", w), g["elevation_count"], w + ".elevations",
                "GLSY")
        M.equal(M.get(jg, "order", "u32", w), g["order"], w + ".order", "GLSY")
    # ray_stats (optional)
    if "ray_stats" in meta:
        stats = M.typed(meta["ray_stats"], "array", "ray_stats")
        if len(stats) != len(bake.objects):
            fail("META: ray_stats has %d entries for %d objects" % (len(stats), len(bake.objects)))
        for k, (st, obj) in enumerate(zip(stats, bake.objects)):
            w = "ray_stats[%d]" % k
            M.typed(st, "object", w)
            M.equal(M.get(st, "object", "string", w), obj.name, w + ".object", "objects[].name")
            v = {key: M.get(st, key, "u64", w) for key in
                 ("points", "rays", "backface_hits", "inside_points", "inside_rays")}
            if v["backface_hits"] > v["rays"]:
                fail("META: %s.backface_hits %d > rays %d" % (w, v["backface_hits"], v["rays"]))
            if v["inside_rays"] > v["rays"]:
                fail("META: %s.inside_rays %d > rays %d" % (w, v["inside_rays"], v["rays"]))
            if v["inside_points"] > v["points"]:
                fail("META: %s.inside_points %d > points %d"
                     % (w, v["inside_points"], v["points"]))
    # shard and point ranges (binary, listed under §4.11)
    if binf["shard_count"] == 1:
        for obj in bake.objects:
            if obj.point_first != 0 or obj.points_in_file != obj.point_count:
                fail("object %d (%s): unsharded bake holds points [%d, +%d) of %d" % (
                    obj.index, short(obj.name), obj.point_first, obj.points_in_file,
                    obj.point_count))
    return meta


def check_reflectance_settings(M: Meta, bake: Bake, settings: dict) -> None:
    """§3.14 / §3.9 for a file with a reflectance field: `settings.pixel_samples` (a per-pixel
    bake's, mandatory here since RFLD is 1.1) and `settings.reflectance` =
    `{"directions": [W, H], "bounces", "rays", "pixel_samples", "geometry": [{"object": name,
    "geometry_hash": "0x…"}]}`, which must agree with RFLD, BINF and settings.pixel_samples.
    The meshes are not in the file, so the hashes cannot be recomputed: only their form is
    checked."""
    field, binf = bake.field, bake.binf
    if "pixel_samples" not in settings:
        fail("META: settings.pixel_samples missing in a file with a reflectance field")
    refl = M.get(settings, "reflectance", "object", "settings")
    w = "settings.reflectance"
    directions = M.get(refl, "directions", "array", w)
    if len(directions) != 2 or not all(is_int(v) and 0 <= v <= U32_MAX for v in directions):
        fail("META: %s.directions must be an array of two u32 integers [W, H], got %s"
             % (w, short(directions)))
    if directions != [field["W"], field["H"]]:
        fail("META: %s.directions %s, but RFLD says [%d, %d]"
             % (w, short(directions), field["W"], field["H"]))
    M.equal(M.get(refl, "bounces", "u32", w), binf["bounces"], w + ".bounces", "BINF bounces")
    M.equal(M.get(refl, "rays", "u32", w), binf["rays_per_point"], w + ".rays",
            "BINF rays_per_point")
    M.equal(M.get(refl, "pixel_samples", "u32", w), settings["pixel_samples"],
            w + ".pixel_samples", "settings.pixel_samples")
    geometry = M.get(refl, "geometry", "array", w)
    if not geometry:
        fail("META: %s.geometry is empty (it lists the scene's meshes)" % w)
    names = set()
    for k, g in enumerate(geometry):
        wk = "%s.geometry[%d]" % (w, k)
        M.typed(g, "object", wk)
        name = M.get(g, "object", "string", wk)
        if not name:
            fail("META: %s.object is empty" % wk)
        if name in names:
            fail("META: %s.object %s named twice" % (wk, short(name)))
        names.add(name)
        gh = M.get(g, "geometry_hash", "string", wk)
        if not re.fullmatch(r"0x[0-9a-f]{16}", gh):
            fail("META: %s.geometry_hash %s is not 0x + 16 lower-case hex digits"
                 % (wk, short(gh)))


def check_lightmaps(M: Meta, bake: Bake, settings: dict) -> None:
    """§3.9 `settings.lightmaps` of a per-texel bake: one entry per object, in object order;
    `null` exactly for an object baked per vertex (no CVRG, §3.1), else
    `{"object": name, "width": W, "height": H, "uv_set": k, "uv_hash": "…"}` with the BINF
    lightmap size and the FNV-1a 64 of the UVs as a decimal string (the UVs are not in the
    file, so the hash itself cannot be recomputed here); or (1.3, §3.9.3) a generated
    `atlas` of per-corner UVs in place of `uv_set`, whose hash is recomputed."""
    binf = bake.binf
    lightmaps = M.get(settings, "lightmaps", "array", "settings")
    if len(lightmaps) != len(bake.objects):
        fail("META: settings.lightmaps has %d entries for %d objects"
             % (len(lightmaps), len(bake.objects)))
    for obj, entry in zip(bake.objects, lightmaps):
        w = "settings.lightmaps[%d]" % obj.index
        if entry is None:
            if obj.coverage is not None:
                fail("META: %s is null, but object %d (%s) is lightmapped (CVRG section %d)"
                     % (w, obj.index, short(obj.name), obj.coverage_section))
            continue
        M.typed(entry, "object", w)
        if obj.coverage is None:
            fail("META: %s is not null, but object %d (%s) has no CVRG (baked per vertex)"
                 % (w, obj.index, short(obj.name)))
        M.equal(M.get(entry, "object", "string", w), obj.name, w + ".object", "OBJT")
        M.equal(M.get(entry, "width", "u32", w), binf["width"], w + ".width", "BINF")
        M.equal(M.get(entry, "height", "u32", w), binf["height"], w + ".height", "BINF")
        has_set, has_atlas = "uv_set" in entry, "atlas" in entry
        if has_set and has_atlas:
            fail("META: %s has both uv_set and atlas (§3.9.3: one or the other)" % w)
        if not has_atlas:
            M.get(entry, "uv_set", "u32", w)  # TEXCOORD_k; §3.9 gives no range: u32 assumed
        uv_hash = M.get(entry, "uv_hash", "string", w)
        # a u64 as a decimal string; §3.9 does not repeat seed's "no sign or leading zeros"
        if not re.fullmatch(r"[0-9]{1,20}", uv_hash) or int(uv_hash) > U64_MAX:
            fail("META: %s.uv_hash %s is not a decimal u64 string" % (w, short(uv_hash)))
        if has_atlas:
            uvs = atlas_corner_uvs(M.get(entry, "atlas", "array", w), obj, w)
            h = fnv1a64(uvs.astype("<f4").tobytes())
            if str(h) != uv_hash:
                fail("META: %s.uv_hash %s is not the FNV-1a 64 of its atlas UVs (%d, §3.9.3)"
                     % (w, short(uv_hash), h))
            obj.atlas_uvs = uvs


ATLAS_QUANTUM = 1 << 24


def atlas_corner_uvs(atlas: list, obj, w: str) -> np.ndarray:
    """§3.9.3: a generated atlas is 6T integers in 0 … 2^24, T the object's MESH triangle
    count when it has a MESH; corner k of triangle t has UV (a, b) / 2^24 with a, b at
    6t + 2k and 6t + 2k + 1. Returns the UVs as float32 [T][3][2]."""
    if len(atlas) % 6 != 0:
        fail("META: %s.atlas has %d integers, not a multiple of 6" % (w, len(atlas)))
    if obj.mesh is not None and len(atlas) != 6 * obj.mesh["T"]:
        fail("META: %s.atlas has %d integers for %d MESH triangles (6 per triangle)"
             % (w, len(atlas), obj.mesh["T"]))
    for k, a in enumerate(atlas):
        if not is_int(a) or not 0 <= a <= ATLAS_QUANTUM:
            fail("META: %s.atlas[%d] is %s, not an integer in 0 … 2^24" % (w, k, short(a)))
    values = np.array(atlas, dtype=np.float64) / ATLAS_QUANTUM
    return values.astype(np.float32).reshape(-1, 3, 2)


# --------------------------------------------------------------------------------------------
# --dump
# --------------------------------------------------------------------------------------------


def block_values(bake: Bake, block) -> np.ndarray:
    """The block's coefficients, [point][channel][coefficient] flat: the XFER scalars viewed
    in place, or a CPCA block's f32 reconstruction (§3.13)."""
    return block["values"]


def dump(bake: Bake) -> dict:
    binf = bake.binf
    objects = []
    for obj in bake.objects:
        blocks = []
        for block in obj.blocks:
            values = block_values(bake, block)
            f32 = values.astype("<f4")  # f16 -> f32 is exact
            blocks.append({
                "kind": KIND_NAMES[block["kind"]],
                "bounces": block["bounces"],
                "crc32_f32": zlib.crc32(f32.tobytes()),
                "sum": float(values.astype(np.float64).sum()),
                "cpca": None if block["cpca"] is None else {
                    "clusters": block["cpca"]["K"],
                    "components": block["cpca"]["M"],
                    "dimension": block["cpca"]["D"],
                    "rel_error": float(block["cpca"]["rel_error"]),
                },
            })
        mesh = None
        if obj.mesh is not None:
            m = obj.mesh
            mesh = {"vertices": m["V"], "triangles": m["T"],
                    "crc32_positions": zlib.crc32(m["positions_raw"]),
                    "crc32_normals": zlib.crc32(m["normals_raw"]),
                    "crc32_triangles": zlib.crc32(m["triangles_raw"])}
        coverage = None
        if obj.coverage is not None:
            hits = obj.coverage["hits"]
            coverage = {"pixel_samples": obj.coverage["K"],
                        "hits_sum": int(hits.astype(np.uint64).sum()),
                        "covered_points": int(np.count_nonzero(hits))}
        objects.append({
            "name": obj.name,
            "geometry_hash": "0x%016x" % obj.geometry_hash,
            "recomputed_hash": None if obj.mesh is None else "0x%016x" % obj.mesh["hash"],
            "point_count": obj.point_count,
            "point_first": obj.point_first,
            "points_in_file": obj.points_in_file,
            "order": obj.order,
            "channels": obj.channels,
            "blocks": blocks,
            "mesh": mesh,
            "coverage": coverage,
        })
    env = None
    if bake.env is not None:
        env = {"order": bake.env["order"],
               "values": [float(v) for v in bake.env["values"]]}
    return {
        "version": [bake.major, bake.minor],
        "scalar_type": SCALAR_TYPES[bake.scalar_type][0],
        "sample_kind": SAMPLE_KINDS[binf["sample_kind"]],
        "width": binf["width"],
        "height": binf["height"],
        "bounces": binf["bounces"],
        "rays_per_point": binf["rays_per_point"],
        "seed": str(binf["seed"]),
        "shard": [binf["shard_index"], binf["shard_count"]],
        "objects": objects,
        "environment": env,
        "brdfs": [{"material": b["material"], "lobe": LOBE_NAMES[b["lobe"]],
                   "exponent": None if b["lobe"] == 1 else float(b["exponent"]),
                   "order": b["order"], "values": [float(v) for v in b["values"]]}
                  for b in bake.brdfs],
        "glossy": [{"material": g["material"], "order": g["order"],
                    "elevations": [float(v) for v in g["elevations"]],
                    "crc32_values": zlib.crc32(g["values_raw"])}
                   for g in bake.glossy],
        "camera": bake.meta.get("camera"),
        "reflectance": field_summary(bake.field),
    }


def field_summary(field):
    """--dump's `reflectance`: null, or the RFLD header and CRC-32s of its arrays (pixels as
    u32 LE, values widened to f32 LE — exact for f16 — in the file's order)."""
    if field is None:
        return None
    values = field["values"]
    return {
        "directions": [field["W"], field["H"]],
        "channels": field["channels"],
        "scalar_type": field["scalar"],
        "pixels": field["P"],
        "first_pixel": int(field["pixels"][0]) if field["P"] else None,
        "last_pixel": int(field["pixels"][-1]) if field["P"] else None,
        "crc32_pixels": zlib.crc32(field["pixels"].astype("<u4").tobytes()),
        "crc32_f32": field_crc32_f32(values),
        "sum": float(values.astype(np.float64).sum()),
        "max": float(values.max()) if values.size else 0.0,
        "zero_values": int(values.size - np.count_nonzero(values)),
    }


def field_crc32_f32(values: np.ndarray) -> int:
    crc = 0
    for start in range(0, values.size, FIELD_CHUNK):
        crc = zlib.crc32(values[start:start + FIELD_CHUNK].astype("<f4").tobytes(), crc)
    return crc


def write_field(path: str, field) -> None:
    """--field-out: the held pixel indices (P × u32 LE), then every value widened to f32 LE
    (3·W·H·P, [pixel held][channel][direction]); exact for f16 files."""
    with open(path, "wb") as f:
        f.write(field["pixels"].astype("<u4").tobytes())
        values = field["values"]
        for start in range(0, values.size, FIELD_CHUNK):
            f.write(values[start:start + FIELD_CHUNK].astype("<f4").tobytes())


# --------------------------------------------------------------------------------------------
# --relight
# --------------------------------------------------------------------------------------------


def parse_albedo(text: str):
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = None
    if values is None or len(values) != 3 or not all(math.isfinite(v) and v >= 0
                                                      for v in values):
        raise PrtbError("bad --albedo %r: expected R,G,B (three finite numbers >= 0)" % text)
    return values


def relight(bake: Bake, name: str, albedo, order=None):
    """Exit radiance of every point of object `name` (§3.4, §3.6). Returns (first, rgb[P,3])."""
    if bake.field is not None:
        # §3.14 gives the integral ∫ R(ω) L(ω) dω but not its quadrature over the W×H grid
        # (cell weights, how L is sampled per cell) and the background term needs the scene's
        # geometry, which a field file does not hold: no relighting of fields here.
        fail("--relight of a reflectance field (RFLD) is not implemented: SPEC §3.14 does not "
             "define its discretisation, and the background term needs the scene")
    obj = next((o for o in bake.objects if o.name == name), None)
    if obj is None:
        fail("no object named %s (objects: %s)"
             % (short(name), ", ".join(short(o.name) for o in bake.objects)))
    if bake.env is None:
        fail("the file has no environment (ENVL section) to relight with")
    inter = [b for b in obj.blocks if b["kind"] == 4]
    if inter:
        block = max(inter, key=lambda b: b["bounces"])
    else:
        block = next((b for k in (2, 1) for b in obj.blocks if b["kind"] == k), None)
    if block is None:
        fail("object %s has no diffuse transfer block" % short(name))
    n = min(obj.order, bake.env["order"], order if order is not None else obj.order)
    nn = n * n
    t = block_values(bake, block).astype(np.float64).reshape(
        obj.points_in_file, obj.channels, obj.order * obj.order)[:, :, :nn]
    en = bake.env["order"]
    light = bake.env["values"].astype(np.float64).reshape(3, en * en)[:, :nn]
    if obj.channels == 3:
        rgb = np.einsum("pci,ci->pc", t, light)
    else:
        rgb = t[:, 0, :] @ light.T
    if not bake.meta.get("settings", {}).get("albedo_in_transfer", False):
        rgb = rgb * (np.asarray(albedo, dtype=np.float64) / math.pi)
    return obj.point_first, rgb


def write_colours(path: str, first: int, rgb: np.ndarray) -> None:
    with open(path, "w", encoding="ascii", newline="\n") as f:
        f.write("point,r,g,b\n")
        for row, (r, g, b) in enumerate(rgb.tolist()):
            f.write("%d,%r,%r,%r\n" % (first + row, r, g, b))


# --------------------------------------------------------------------------------------------
# --self-test
# --------------------------------------------------------------------------------------------


def try_parse(data: bytes):
    """'ok', 'refused' or ('crash', text)."""
    try:
        parse(data)
        return "ok"
    except PrtbError:
        return "refused"
    except Exception:  # noqa: BLE001 - a crash is what the self-test looks for
        return ("crash", traceback.format_exc(limit=3).strip().splitlines()[-1])


def fix_crcs(buf: bytearray, section_index=None) -> None:
    """Recompute one section's CRC (if given) and the header CRC, in place."""
    table_offset = struct.unpack_from("<Q", buf, 32)[0]
    count = struct.unpack_from("<I", buf, 40)[0]
    if section_index is not None:
        e = table_offset + ENTRY_SIZE * section_index
        _tag, _flags, offset, length = struct.unpack_from("<4sIQQ", buf, e)
        struct.pack_into("<I", buf, e + 24, zlib.crc32(buf[offset:offset + length]))
    crc = zlib.crc32(buf[table_offset:table_offset + ENTRY_SIZE * count], zlib.crc32(buf[0:60]))
    struct.pack_into("<I", buf, 60, crc)


def replace_meta(data: bytes, text: str) -> bytes:
    """The file with its META payload replaced by `text` (UTF-8): the sections after META move
    by the change of its aligned length (a multiple of payload_alignment, so every offset stays
    aligned and the zero padding stays zero), then file_size, the META entry's length and CRC
    and the header CRC are rewritten. The file must be valid and have its table before META."""
    payload = text.encode("utf-8")
    table_offset = struct.unpack_from("<Q", data, 32)[0]
    count, _entry, alignment = struct.unpack_from("<3I", data, 40)
    entries = [struct.unpack_from("<4sIQQII", data, table_offset + ENTRY_SIZE * i)
               for i in range(count)]
    meta_index = next(i for i, e in enumerate(entries) if e[0] == b"META")
    meta_offset, meta_length = entries[meta_index][2], entries[meta_index][3]

    def aligned(x):
        return -(-x // alignment) * alignment

    old_end = aligned(meta_offset + meta_length)
    new_end = aligned(meta_offset + len(payload))
    if old_end >= len(data):  # META is the last payload: the file ends where it ends
        old_end, new_end = len(data), meta_offset + len(payload)
    delta = new_end - old_end
    buf = bytearray(data[:meta_offset]) + payload
    buf += bytes(new_end - len(buf)) + data[old_end:]
    struct.pack_into("<Q", buf, 24, len(buf))
    for i, (_tag, _flags, offset, length, _crc, _res) in enumerate(entries):
        e = table_offset + ENTRY_SIZE * i
        if i == meta_index:
            struct.pack_into("<Q", buf, e + 16, len(payload))
            struct.pack_into("<I", buf, e + 24, zlib.crc32(payload))
        elif offset >= old_end and (length or offset > meta_offset):
            struct.pack_into("<Q", buf, e + 8, offset + delta)
    fix_crcs(buf)
    return bytes(buf)


DELETE = object()  # texel_cases: remove the key instead of setting it


def meta_case_adder(data: bytes, original: str, cases: list):
    """A function adding the case `change(META JSON)` (rewritten at its new length) to
    `cases`, labelled, refused unless `must_refuse` is False."""
    def meta_case(label, change, must_refuse=True):
        meta = json.loads(original)
        change(meta)
        cases.append(("META " + label, replace_meta(data, json.dumps(meta, indent=2)),
                      must_refuse))
    return meta_case


def setter(path, value):
    """A META change setting the key at `path` to `value` (or removing it: `DELETE`)."""
    def change(meta):
        node = meta
        for key in path[:-1]:
            node = node[key]
        if value is DELETE:
            del node[path[-1]]
        else:
            node[path[-1]] = value
    return change


def texel_cases(data: bytes, bake: Bake, rng: random.Random):
    """Targeted mutations of a VALID per-texel bake (§3.1, §3.9, §3.11, §4.9), CRCs repaired:
    a list of (label, file bytes, must_refuse). must_refuse False marks a control variant that
    the spec allows and that must therefore still be accepted."""
    cases = []
    sec = {s.tag: s for s in bake.sections if s.tag in TAGS_ONCE}
    binf, objt = sec[b"BINF"], sec[b"OBJT"]
    objt_rs = struct.unpack_from("<I", data, objt.offset + 4)[0]

    def patched(pos, new, section):
        buf = bytearray(data)
        buf[pos:pos + len(new)] = new
        fix_crcs(buf, section.index)
        return bytes(buf)

    W, H = bake.binf["width"], bake.binf["height"]
    cases += [
        ("BINF sample_kind 1 (per-vertex)", patched(binf.offset, struct.pack("<I", 1), binf),
         True),
        ("BINF sample_kind 2 (per-pixel)", patched(binf.offset, struct.pack("<I", 2), binf),
         True),
        ("BINF sample_kind 4", patched(binf.offset, struct.pack("<I", 4), binf), True),
        ("BINF width 0", patched(binf.offset + 8, struct.pack("<I", 0), binf), True),
        ("BINF height 0", patched(binf.offset + 12, struct.pack("<I", 0), binf), True),
        ("BINF width + 1", patched(binf.offset + 8, struct.pack("<I", W + 1), binf), True),
        ("BINF height + 1", patched(binf.offset + 12, struct.pack("<I", H + 1), binf), True),
    ]
    for obj in bake.objects:
        rec = objt.offset + 16 + obj.index * objt_rs
        what = "object %d" % obj.index
        if objt_rs < OBJT_RECORD_11:
            continue
        if obj.coverage is None:
            if obj.mesh is not None:  # baked per vertex: V = point_count
                cases.append(("%s (no CVRG) point_count + 1" % what,
                              patched(rec + 16, struct.pack("<Q", obj.point_count + 1), objt),
                              True))
            continue
        cov = bake.sections[obj.coverage["section"]]
        hits = obj.coverage["hits"]
        cases += [
            ("%s (CVRG) point_count + 1" % what,
             patched(rec + 16, struct.pack("<Q", obj.point_count + 1), objt), True),
            ("%s coverage_section none" % what,
             patched(rec + 60, struct.pack("<I", NONE_INDEX), objt), True),
            ("%s CVRG K = 2" % what, patched(cov.offset + 4, struct.pack("<I", 2), cov), True),
            ("%s CVRG K = 0" % what, patched(cov.offset + 4, struct.pack("<I", 0), cov), True),
        ]
        if hits.size:
            for _ in range(3):
                p = rng.randrange(hits.size)
                cases.append(("%s hits[%d] = 2 > K" % (what, p),
                              patched(cov.offset + 16 + 4 * p, struct.pack("<I", 2), cov), True))
        # hits 0 where an XFER block is non-zero: the transfer must be zero there (§3.11)
        nonzero = np.zeros(hits.size, dtype=bool)
        for block in obj.blocks:
            if block["cpca"] is None:
                nonzero |= (block["values"].reshape(hits.size, -1) != 0).any(axis=1)
        live = np.flatnonzero(nonzero & (hits == 1))
        for p in sorted(rng.sample(list(live), min(3, live.size))):
            cases.append(("%s hits[%d] = 0 under non-zero transfer" % (what, p),
                          patched(cov.offset + 16 + 4 * int(p), struct.pack("<I", 0), cov),
                          True))
        # hits 1 over zero transfer breaks no rule (an uncovered texel must have zero transfer,
        # not the other way round): a control
        empty = np.flatnonzero(hits == 0)
        if empty.size:
            p = int(empty[rng.randrange(empty.size)])
            cases.append(("%s hits[%d] = 1 over zero transfer (control)" % (what, p),
                          patched(cov.offset + 16 + 4 * p, struct.pack("<I", 1), cov), False))

    # META JSON, rewritten at its new length
    meta_section = next(s for s in bake.sections if s.tag == b"META")
    table_offset = struct.unpack_from("<Q", data, 32)[0]
    if table_offset + ENTRY_SIZE * len(bake.sections) > meta_section.offset:
        return cases
    original = bytes(meta_section.payload).decode("utf-8")

    meta_case = meta_case_adder(data, original, cases)

    meta_case("re-serialised unchanged (control)", lambda meta: None, False)
    meta_case("settings.pixel_samples 1 (control)", setter(("settings", "pixel_samples"), 1),
              False)
    meta_case("settings.pixel_samples 2", setter(("settings", "pixel_samples"), 2))
    meta_case("sample_kind.kind pixel", setter(("sample_kind", "kind"), "pixel"))
    meta_case("sample_kind vertex", setter(("sample_kind",), {"kind": "vertex"}))
    meta_case("sample_kind.width + 1", setter(("sample_kind", "width"), W + 1))
    meta_case("sample_kind.height missing", setter(("sample_kind", "height"), DELETE))
    meta_case("camera not null", setter(("camera",), {
        "model": "pinhole", "eye": [0, 0, 1], "target": [0, 0, 0], "up": [0, 1, 0],
        "fov_y_degrees": 40.0, "width": W, "height": H}))
    meta_case("settings.lightmaps missing", setter(("settings", "lightmaps"), DELETE))
    meta_case("settings.lightmaps an object", setter(("settings", "lightmaps"), {}))
    meta_case("settings.lightmaps one short",
              lambda meta: meta["settings"]["lightmaps"].pop())
    meta_case("settings.lightmaps one extra",
              lambda meta: meta["settings"]["lightmaps"].append(None))
    lit = [o for o in bake.objects if o.coverage is not None]
    unlit = [o for o in bake.objects if o.coverage is None]
    lightmaps = json.loads(original).get("settings", {}).get("lightmaps")
    if isinstance(lightmaps, list) and lightmaps != lightmaps[::-1]:
        meta_case("settings.lightmaps reversed",
                  lambda meta: meta["settings"]["lightmaps"].reverse())
    for obj in lit:
        k = obj.index
        path = ("settings", "lightmaps", k)
        meta_case("lightmaps[%d] null" % k, setter(path, None))
        meta_case("lightmaps[%d] a string" % k, setter(path, "uv0"))
        if "atlas" in lightmaps[k]:
            atlas_cases(meta_case, setter, path, lightmaps[k], obj, W, H)
            continue
        for key in ("object", "width", "height", "uv_set", "uv_hash"):
            meta_case("lightmaps[%d].%s missing" % (k, key), setter(path + (key,), DELETE))
        for key, bad in (("object", obj.name + "x"), ("object", None), ("width", W + 1),
                         ("width", str(W)), ("height", H - 1), ("height", float(H)),
                         ("uv_set", -1), ("uv_set", 1.5), ("uv_set", "0"), ("uv_set", None),
                         ("uv_set", 2**32), ("uv_hash", 12345), ("uv_hash", "abc"),
                         ("uv_hash", ""), ("uv_hash", "-1"), ("uv_hash", "0x1f"),
                         ("uv_hash", "18446744073709551616"), ("uv_hash", " 1")):
            meta_case("lightmaps[%d].%s = %s" % (k, key, short(bad)),
                      setter(path + (key,), bad))
        for key, ok in (("uv_hash", "0"), ("uv_hash", "18446744073709551615"),
                        ("uv_set", 7), ("comment", "an unknown field")):
            meta_case("lightmaps[%d].%s = %s (control)" % (k, key, short(ok)),
                      setter(path + (key,), ok), False)
        meta_case("objects[%d].coverage null" % k, setter(("objects", k, "coverage"), None))
        meta_case("objects[%d].coverage.pixel_samples 2" % k,
                  setter(("objects", k, "coverage", "pixel_samples"), 2))
    for obj in unlit:
        k = obj.index
        entry = {"object": obj.name, "width": W, "height": H, "uv_set": 0, "uv_hash": "1"}
        meta_case("lightmaps[%d] not null for an object without CVRG" % k,
                  setter(("settings", "lightmaps", k), entry))
    return cases


def atlas_cases(meta_case, setter, path, entry, obj, W, H):
    """Mutations of a generated-atlas lightmaps entry (§3.9.3): every one must be refused."""
    k = obj.index
    atlas = entry["atlas"]
    for key in ("object", "width", "height", "atlas", "uv_hash"):
        meta_case("lightmaps[%d].%s missing" % (k, key), setter(path + (key,), DELETE))
    changed = list(atlas)
    changed[0] = (changed[0] + 1) % ATLAS_QUANTUM
    for key, bad in (("object", obj.name + "x"), ("width", W + 1), ("height", H - 1),
                     ("uv_set", 0), ("atlas", atlas[:-6]), ("atlas", atlas + [0] * 6),
                     ("atlas", [ATLAS_QUANTUM + 1] + atlas[1:]), ("atlas", [-1] + atlas[1:]),
                     ("atlas", [0.5] + atlas[1:]), ("atlas", "0"), ("atlas", changed),
                     ("uv_hash", "0"), ("uv_hash", "abc")):
        meta_case("lightmaps[%d].%s = %s" % (k, key, short(bad)), setter(path + (key,), bad))
    meta_case("lightmaps[%d].comment (control)" % k,
              setter(path + ("comment",), "an unknown field"), False)


def field_cases(data: bytes, bake: Bake, rng: random.Random):
    """Targeted mutations of a VALID file with a reflectance field (§3.14), CRCs repaired: a
    list of (label, file bytes, must_refuse); must_refuse False marks an allowed control."""
    cases = []
    field = bake.field
    sec = {s.tag: s for s in bake.sections if s.tag in TAGS_ONCE}
    binf = sec[b"BINF"]
    rf = bake.sections[field["section"]]
    o = rf.offset
    W, H, P = field["W"], field["H"], field["P"]
    image = bake.binf["width"] * bake.binf["height"]
    ssize = SCALAR_TYPES[bake.scalar_type][2]
    values_at = o + RFLD_HEADER + 4 * P

    def patched(pos, new, section):
        buf = bytearray(data)
        buf[pos:pos + len(new)] = new
        fix_crcs(buf, section.index)
        return bytes(buf)

    def flags(value):
        buf = bytearray(data)
        table_offset = struct.unpack_from("<Q", buf, 32)[0]
        struct.pack_into("<I", buf, table_offset + ENTRY_SIZE * rf.index + 4, value)
        fix_crcs(buf)
        return bytes(buf)

    u32 = lambda v: struct.pack("<I", v)  # noqa: E731
    u64 = lambda v: struct.pack("<Q", v)  # noqa: E731
    cases += [
        ("RFLD flags 0 (not REQUIRED)", flags(0), True),
        ("RFLD flags REQUIRED | hint bit 16 (control)", flags(FLAG_REQUIRED | 1 << 16), False),
        ("BINF per-vertex (sample_kind 1, image 0x0)",
         patched(binf.offset, struct.pack("<4I", 1, bake.binf["bounces"], 0, 0), binf), True),
        ("BINF sample_kind 3", patched(binf.offset, u32(3), binf), True),
        ("BINF shard_count 2", patched(binf.offset + 24, u32(2), binf), True),
        ("header minor 0", patched(12, u32(0), binf), True),
        ("RFLD W = 1", patched(o, u32(1), rf), True),
        ("RFLD W = 0", patched(o, u32(0), rf), True),
        ("RFLD H = 0", patched(o + 4, u32(0), rf), True),
        ("RFLD W + 1", patched(o, u32(W + 1), rf), True),
        ("RFLD H + 1", patched(o + 4, u32(H + 1), rf), True),
        ("RFLD W×H > 2^24", patched(o, u32(2**24 // H + 1), rf), True),
        ("RFLD W = 2^32-1", patched(o, u32(U32_MAX), rf), True),
        ("RFLD channels 1", patched(o + 8, u32(1), rf), True),
        ("RFLD channels 4", patched(o + 8, u32(4), rf), True),
        ("RFLD P + 1", patched(o + 16, u64(P + 1), rf), True),
        ("RFLD P = 2^63", patched(o + 16, u64(2**63), rf), True),
        ("RFLD P = image + 1", patched(o + 16, u64(image + 1), rf), True),
        ("RFLD reserved fields non-zero (control)",
         patched(o + 12, u32(7), rf), False),
    ]
    if P:
        cases += [
            ("RFLD P - 1", patched(o + 16, u64(P - 1), rf), True),
            ("RFLD last pixel = image size",
             patched(o + RFLD_HEADER + 4 * (P - 1), u32(image), rf), True),
            ("RFLD last pixel = 2^32-1",
             patched(o + RFLD_HEADER + 4 * (P - 1), u32(U32_MAX), rf), True),
        ]
    if P >= 2:
        k = rng.randrange(1, P)
        prev = int(field["pixels"][k - 1])
        cases += [
            ("RFLD pixels[%d] = pixels[%d] (repeat)" % (k, k - 1),
             patched(o + RFLD_HEADER + 4 * k, u32(prev), rf), True),
            ("RFLD pixels[0] > pixels[1]",
             patched(o + RFLD_HEADER, u32(int(field["pixels"][1]) + 1), rf), True),
        ]
    bad_values = ((("NaN", float("nan")), ("+inf", float("inf")), ("-inf", float("-inf")),
                   ("-1e-3", -1e-3), ("-65504", -65504.0)))
    count = field["values"].size
    for label, v in bad_values:
        for _ in range(2):
            k = rng.randrange(count) if count else None
            if k is None:
                break
            new = (struct.pack("<f", v) if ssize == 4 else
                   np.array([v], dtype="<f2").tobytes())
            cases.append(("RFLD value %d = %s" % (k, label),
                          patched(values_at + ssize * k, new, rf), True))
    if count:
        k = rng.randrange(count)
        neg_zero = struct.pack("<f", -0.0) if ssize == 4 else np.array([-0.0], "<f2").tobytes()
        cases.append(("RFLD value %d = -0.0 (control)" % k,
                      patched(values_at + ssize * k, neg_zero, rf), False))

    meta_section = sec[b"META"]
    table_offset = struct.unpack_from("<Q", data, 32)[0]
    if table_offset + ENTRY_SIZE * len(bake.sections) > meta_section.offset:
        return cases
    original = bytes(meta_section.payload).decode("utf-8")

    meta_case = meta_case_adder(data, original, cases)

    r = ("settings", "reflectance")
    meta_case("re-serialised unchanged (control)", lambda meta: None, False)
    meta_case("settings.reflectance unknown key (control)", setter(r + ("note",), "x"), False)
    meta_case("settings.reflectance missing", setter(r, DELETE))
    meta_case("settings.reflectance null", setter(r, None))
    meta_case("settings.pixel_samples missing", setter(("settings", "pixel_samples"), DELETE))
    for key in ("directions", "bounces", "rays", "pixel_samples", "geometry"):
        meta_case("settings.reflectance.%s missing" % key, setter(r + (key,), DELETE))
    for key, bad in (("directions", [W + 1, H]), ("directions", [W, H + 1]),
                     ("directions", [W, H, 1]), ("directions", [W, float(H)]),
                     ("directions", "%dx%d" % (W, H)),
                     ("bounces", bake.binf["bounces"] + 1), ("bounces", -1),
                     ("rays", bake.binf["rays_per_point"] + 1), ("rays", "16"),
                     ("pixel_samples", 0), ("geometry", []), ("geometry", {}),
                     ("geometry", [None]), ("geometry", [{"object": "a"}]),
                     ("geometry", [{"object": "", "geometry_hash": "0x" + "0" * 16}]),
                     ("geometry", [{"object": "a", "geometry_hash": "0x" + "A" * 16}]),
                     ("geometry", [{"object": "a", "geometry_hash": "0x" + "0" * 15}]),
                     ("geometry", [{"object": "a", "geometry_hash": "0x" + "0" * 16}] * 2)):
        meta_case("settings.reflectance.%s = %s" % (key, short(bad)), setter(r + (key,), bad))
    meta_case("settings.pixel_samples + 1 (reflectance's differs)",
              setter(("settings", "pixel_samples"),
                     json.loads(original)["settings"].get("pixel_samples", 1) + 1))
    meta_case("camera null", setter(("camera",), None))
    return cases


def self_test(path: str, seed: int, cli_samples: int = 12) -> int:
    with open(path, "rb") as f:
        data = f.read()
    bake = parse(data)  # must be valid to start with
    n = len(data)
    rng = random.Random(seed)
    table_offset = struct.unpack_from("<Q", data, 32)[0]
    table_end = table_offset + ENTRY_SIZE * len(bake.sections)
    edges = set(range(0, min(n, table_end)))
    for s in bake.sections:
        if s.length:
            edges.update({s.offset, s.offset + 1, s.offset + s.length - 2, s.offset + s.length - 1})
    occupied = [(0, table_end)] + [(s.offset, s.offset + s.length) for s in bake.sections]
    occupied.sort()
    padding = []
    cursor = 0
    for a, b in occupied + [(n, n)]:
        if a > cursor:
            padding.extend(range(cursor, a))
        cursor = max(cursor, b)
    if len(padding) > 600:
        padding = sorted(rng.sample(padding, 600))
    flips = sorted({p for p in edges if 0 <= p < n} | set(padding)
                   | {rng.randrange(n) for _ in range(1500)})
    results = {"flip": [0, 0], "padding": [0, 0], "truncate": [0, 0], "repaired": [0, 0, 0],
               "mesh": [0, 0], "cpca": [0, 0], "texel": [0, 0], "control": [0, 0]}
    crashes = []
    slipped = []
    refused_valid = []  # control variants the spec allows that were refused
    padding_set = set(padding)

    def record(category, outcome, what, must_refuse=True):
        r = results[category]
        r[1] += 1
        if isinstance(outcome, tuple):
            crashes.append("%s: %s" % (what, outcome[1]))
        elif outcome == "refused":
            r[0] += 1
        elif must_refuse:
            slipped.append(what)

    # 1. single-byte flips, no CRC repair: every one must be refused
    for p in flips:
        buf = bytearray(data)
        buf[p] ^= rng.randrange(1, 256)
        outcome = try_parse(bytes(buf))
        record("flip", outcome, "flip at %d" % p)
        if p in padding_set:
            record("padding", outcome, "padding flip at %d" % p)
    # 2. truncations and extensions: every one must be refused
    lengths = set(range(0, min(n, 160)))
    for s in bake.sections:
        lengths.update({s.offset - 1, s.offset, s.offset + 1, s.offset + s.length - 1})
    lengths.update(rng.randrange(n) for _ in range(300))
    lengths = sorted(x for x in lengths if 0 <= x < n)
    for length in lengths:
        record("truncate", try_parse(data[:length]), "truncation to %d" % length)
    for extra in (b"\x00", b"\x00" * 64, b"junk"):
        record("truncate", try_parse(data + extra), "extension by %d bytes" % len(extra))
    # 3. mutations with repaired CRCs: must never crash; MESH position/triangle bytes must be
    #    refused (the recomputed geometry hash changes); others may read as valid files.
    targets = [s for s in bake.sections if s.length]
    for _ in range(1200):
        buf = bytearray(data)
        choice = rng.random()
        if choice < 0.25:  # header field or table entry, header CRC repaired
            p = rng.choice([x for x in range(8, table_end) if not 60 <= x < 64])
            section_index = None
        else:
            s = rng.choice(targets)
            # bias towards the start of the payload, where the counts and offsets are
            p = s.offset + (rng.randrange(min(s.length, 64)) if rng.random() < 0.6
                            else rng.randrange(s.length))
            section_index = s.index
        mode = rng.random()
        if mode < 0.5:
            buf[p] ^= 1 << rng.randrange(8)
        elif mode < 0.8:
            buf[p] = rng.choice((0x00, 0xFF, 0x7F, 0x80, 0x01))
        else:
            buf[p] = rng.randrange(256)
        if buf[p] == data[p]:
            buf[p] ^= 0x01
        fix_crcs(buf, section_index)
        outcome = try_parse(bytes(buf))
        r = results["repaired"]
        r[2] += 1
        if isinstance(outcome, tuple):
            crashes.append("repaired mutation at %d: %s" % (p, outcome[1]))
        elif outcome == "refused":
            r[0] += 1
        else:
            r[1] += 1
    for obj in bake.objects:
        if obj.mesh is None or not obj.mesh["V"]:
            continue
        s = bake.sections[obj.mesh["section"]]
        V, T = obj.mesh["V"], obj.mesh["T"]
        spots = [s.offset + 16 + rng.randrange(12 * V) for _ in range(20)]
        if T:
            spots += [s.offset + 16 + 24 * V + rng.randrange(12 * T) for _ in range(20)]
        for p in spots:
            buf = bytearray(data)
            buf[p] ^= 1 << rng.randrange(8)
            fix_crcs(buf, s.index)
            record("mesh", try_parse(bytes(buf)), "repaired MESH mutation at %d" % p)
    # 3b. CPCA blocks (§3.13), CRCs repaired: each of these breaks a rule and must be refused
    blkt_section = next(s for s in bake.sections if s.tag == b"BLKT")
    blkt_rs = struct.unpack_from("<I", data, blkt_section.offset + 4)[0]
    for block in bake.blocks:
        c = block["cpca"]
        if c is None:
            continue
        s = bake.sections[block["section"]]
        K, M, D, P = c["K"], c["M"], c["D"], c["P"]
        o = s.offset
        ids_at = o + CPCA_HEADER + 4 * K * (M + 1) * D
        weights_at = ids_at + 4 * P
        rec = blkt_section.offset + 16 + block["index"] * blkt_rs
        nan = struct.pack("<f", float("nan"))
        cases = [  # (label, position, new bytes, section whose CRC to repair)
            ("object_index", o, struct.pack("<I", block["object_index"] + 1), s.index),
            ("K = 0", o + 4, struct.pack("<I", 0), s.index),
            ("K + 1", o + 4, struct.pack("<I", K + 1), s.index),
            ("M + 1", o + 8, struct.pack("<I", M + 1), s.index),
            ("M = 2^32-1", o + 8, struct.pack("<I", U32_MAX), s.index),
            ("D + 1", o + 12, struct.pack("<I", D + 1), s.index),
            ("P + 1", o + 16, struct.pack("<Q", P + 1), s.index),
            ("P = 2^63", o + 16, struct.pack("<Q", 2**63), s.index),
            ("rel_error NaN", o + 24, struct.pack("<d", float("nan")), s.index),
            ("rel_error inf", o + 24, struct.pack("<d", float("inf")), s.index),
            ("BLKT scalar_type = header's", rec + 20, struct.pack("<I", bake.scalar_type),
             blkt_section.index),
            ("BLKT data_length + 1", rec + 40, struct.pack("<Q", s.length + 1),
             blkt_section.index),
        ]
        for _ in range(4):
            cases.append(("cluster value NaN",
                          o + CPCA_HEADER + 4 * rng.randrange(K * (M + 1) * D), nan, s.index))
        if P:
            for _ in range(4):
                cases.append(("cluster id >= K", ids_at + 4 * rng.randrange(P),
                              struct.pack("<I", rng.randrange(K, U32_MAX + 1)), s.index))
        if P and M:
            for _ in range(4):
                cases.append(("weight NaN", weights_at + 4 * rng.randrange(P * M), nan,
                              s.index))
        for label, pos, new, section_index in cases:
            buf = bytearray(data)
            buf[pos:pos + len(new)] = new
            fix_crcs(buf, section_index)
            record("cpca", try_parse(bytes(buf)),
                   "repaired CPCA mutation (%s, BLKT record %d) at %d"
                   % (label, block["index"], pos))
    # 3c. per-texel bakes (§3.1, §3.9, §3.11): targeted binary and META mutations that must be
    #     refused, and control variants the spec allows that must still be accepted
    targeted = []
    if bake.binf["sample_kind"] == 3:
        targeted = texel_cases(data, bake, rng)
    if bake.field is not None:
        targeted = field_cases(data, bake, rng)
    if targeted:
        for label, buf, must_refuse in targeted:
            outcome = try_parse(buf)
            if must_refuse:
                record("texel", outcome, "targeted mutation (%s)" % label)
            else:
                r = results["control"]
                r[1] += 1
                if isinstance(outcome, tuple):
                    crashes.append("control (%s): %s" % (label, outcome[1]))
                elif outcome == "ok":
                    r[0] += 1
                else:
                    try:
                        parse(buf)
                    except PrtbError as e:
                        refused_valid.append("control (%s) refused: %s" % (label, e))
    # 4. the command line itself on a few corrupted files: exit 1, one line, no traceback
    cli_bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(cli_samples):
            buf = bytearray(data)
            if k % 2:
                buf = buf[:rng.randrange(n)]
            else:
                buf[rng.randrange(n)] ^= 0x55
            bad = os.path.join(tmp, "bad%d.prtb" % k)
            with open(bad, "wb") as f:
                f.write(buf)
            proc = subprocess.run([sys.executable, os.path.abspath(__file__), bad],
                                  capture_output=True, text=True)
            lines = proc.stderr.splitlines()
            if (proc.returncode != 1 or len(lines) != 1 or "Traceback" in proc.stderr
                    or not lines[0].startswith("%s: %s: " % (PROG, bad))):
                cli_bad += 1
                crashes.append("CLI on %s: exit %d, stderr %r"
                               % (bad, proc.returncode, proc.stderr[:200]))
    f, p, t, r, m, c, x, ok = (results[k] for k in ("flip", "padding", "truncate", "repaired",
                                                     "mesh", "cpca", "texel", "control"))
    print("self-test of %s (%d bytes, seed %d)" % (path, n, seed))
    print("  single-byte flips refused:      %d of %d (of which zero padding: %d of %d)"
          % (f[0], f[1], p[0], p[1]))
    print("  truncations/extensions refused: %d of %d" % (t[0], t[1]))
    print("  CRC-repaired mutations:         %d refused, %d read as valid, of %d (no crash "
          "allowed)" % (r[0], r[1], r[2]))
    print("  CRC-repaired MESH mutations:    %d of %d refused (geometry hash)" % (m[0], m[1]))
    if c[1]:
        print("  CRC-repaired CPCA mutations:    %d of %d refused (§3.13 rules)" % (c[0], c[1]))
    if x[1] or ok[1]:
        print("  targeted mutations:             %d of %d refused (per-texel §3.1/§3.9/§3.11 "
              "or field §3.14 rules); "
              "controls accepted: %d of %d" % (x[0], x[1], ok[0], ok[1]))
    print("  command line on corrupted files: %d of %d gave exit 1 and one clean line"
          % (cli_samples - cli_bad, cli_samples))
    caught = f[0] + t[0] + m[0] + c[0] + x[0]
    total = f[1] + t[1] + m[1] + c[1] + x[1]
    print("  caught %d of %d corruptions that must be refused; %d slipped through, %d crashes"
          % (caught, total, len(slipped), len(crashes)))
    if refused_valid:
        print("  %d valid control variants were refused" % len(refused_valid))
    for line in (slipped + crashes + refused_valid)[:20]:
        print("    " + line)
    return 1 if slipped or crashes or refused_valid else 0


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


class UsageError(Exception):
    pass


class Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


def main(argv=None) -> int:
    parser = Parser(prog="prtb_reader.py", description=__doc__.split("\n\n")[0],
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", help="the .prtb file")
    parser.add_argument("--dump", metavar="OUT.json", help="write a JSON summary")
    parser.add_argument("--field-out", metavar="OUT.bin",
                        help="write a reflectance field's pixels (u32) and values (f32), raw LE")
    parser.add_argument("--relight", metavar="OBJECT", help="relight this object's points")
    parser.add_argument("--albedo", metavar="R,G,B", help="diffuse albedo for --relight")
    parser.add_argument("--order", type=int, metavar="N", help="SH order cap for --relight")
    parser.add_argument("--colours", metavar="OUT.csv", help="CSV output of --relight")
    parser.add_argument("--self-test", action="store_true",
                        help="corruption self-check on a valid FILE")
    parser.add_argument("--seed", type=int, default=20240601, help="self-test random seed")
    try:
        args = parser.parse_args(argv)
        if args.relight is not None and (args.albedo is None or args.colours is None):
            raise UsageError("--relight needs --albedo R,G,B and --colours OUT.csv")
        if args.relight is None and (args.albedo is not None or args.colours is not None
                                     or args.order is not None):
            raise UsageError("--albedo, --order and --colours only go with --relight")
        if args.order is not None and args.order < 1:
            raise UsageError("--order must be >= 1")
    except UsageError as e:
        print("%s: %s" % (PROG, str(e).replace("\n", " ")), file=sys.stderr)
        return 1

    path = args.file
    try:
        albedo = parse_albedo(args.albedo) if args.relight is not None else None
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError as e:
            raise PrtbError("cannot read: %s" % (e.strerror or e))
        if args.self_test:
            return self_test(path, args.seed)
        bake = parse(data)
        if args.dump:
            summary = dump(bake)
            try:
                with open(args.dump, "w", encoding="utf-8") as f:
                    json.dump(summary, f, indent=1, allow_nan=False)
                    f.write("\n")
            except OSError as e:
                raise PrtbError("cannot write %s: %s" % (args.dump, e.strerror or e))
        if args.field_out:
            if bake.field is None:
                raise PrtbError("--field-out: the file has no reflectance field (RFLD)")
            try:
                write_field(args.field_out, bake.field)
            except OSError as e:
                raise PrtbError("cannot write %s: %s" % (args.field_out, e.strerror or e))
        if args.relight is not None:
            first, rgb = relight(bake, args.relight, albedo, args.order)
            try:
                write_colours(args.colours, first, rgb)
            except OSError as e:
                raise PrtbError("cannot write %s: %s" % (args.colours, e.strerror or e))
        return 0
    except PrtbError as e:
        message = str(e)
    except MemoryError:
        message = "out of memory while reading the file"
    except Exception as e:  # noqa: BLE001 - never a traceback on bad input
        message = "malformed file (%s: %s)" % (type(e).__name__, e)
    print("%s: %s: %s" % (PROG, path, message.replace("\n", " ").replace("\r", " ")),
          file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
