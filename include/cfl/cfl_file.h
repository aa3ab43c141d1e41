#pragma once
/// @file
/// Saving and loading a built CflModel, so that the expensive precomputation runs once.
///
/// The format (full description, with a byte map, in docs/cfl_file_format.md), version 1:
///
///     offset  size  field
///          0     8  magic 0x89 'C' 'F' 'L' '\r' '\n' 0x1A '\n'  (PNG-style: catches text-mode mangling)
///          8     4  endianness marker 0x01020304, stored as bytes 04 03 02 01
///         12     4  format version (1)
///         16     8  payload size P in bytes
///         24     4  CRC-32 (IEEE 802.3, as zlib's crc32) of the P payload bytes
///         28     4  CRC-32 of bytes 0..27 (the header)
///         32     P  payload: sections, each a 4-byte ASCII tag, a u32 zero, a u64 length L and L bytes
///
/// Every integer and double is little-endian whatever the host (doubles as their IEEE-754 bit pattern),
/// written and read byte by byte, so files move between machines. The sections, in this order, are MESH
/// (vertices, triangles), GRID (origin, voxel size, dims, padding, topology flag), LIST (voxel_list,
/// list_offsets, list_triangles), BNDS (voxel_lower_bound, corner_distance) and STAT (statistics).
/// Sections with an unknown tag are skipped, so a later writer can add data that old readers ignore; a
/// change of meaning bumps the version instead. The Bvh and triangle corners are not stored: loading rebuilds
/// them with makeMeshModel, which is deterministic, so a loaded model answers every query bit-identically to
/// the model that was saved.

#include "cfl/cfl_model.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cfl {

/// The version written by this library. It also reads version 1 files (lists without entry bounds,
/// loaded with every bound 0: correct, only slower to query).
constexpr std::uint32_t kCflFileVersion = 3;

/// The model as the bytes of a version-2 file. O(model size); thread-safe (reads `model` only).
/// Throws cfl::Error when the model breaks an invariant of CflModel (the loader would refuse the result),
/// e.g. a list holding a triangle id out of range.
std::vector<unsigned char> serializeCflModel(const CflModel& model);

/// Parses the bytes of a file written by serializeCflModel. Everything is checked before it is used: size,
/// magic, endianness marker, version, both checksums, every count against the bytes that remain (so a
/// corrupt count never causes a large allocation), every triangle and list id against its range, offsets
/// increasing, list contents sorted by (entry bound, id), array sizes against the grid dims, every double finite (and distances
/// non-negative), the grid against the mesh's bounds, padding and resolution. Any failure throws cfl::Error
/// whose message starts with `name_for_errors` (usually the file path) and says what is wrong, e.g.
/// "robot.cfl: checksum mismatch (payload CRC-32 is 0x1c291ca3, header says 0x5d0f4e12): the file is corrupt".
///
/// A checksum guards against accidental corruption only: a file forged to pass it with wrong lists (but valid
/// structure) would load and give wrong distances. Load only files you or your tools wrote.
/// Time and extra memory are linear in `size`; the Bvh is rebuilt, O(n log n) in the triangle count.
CflModel deserializeCflModel(const unsigned char* data, std::size_t size, const std::string& name_for_errors);

/// Writes `model` to `path` (replacing it) through a temporary file in the same directory that is renamed
/// into place, so readers never see a half-written file. Throws cfl::Error naming the path when the file
/// cannot be written.
void saveCflModel(const CflModel& model, const std::string& path);

/// Reads a model saved by saveCflModel. Throws cfl::Error naming `path` when the file cannot be read or is
/// not a valid CFL file of version 1 or 2 (see deserializeCflModel for what is checked).
CflModel loadCflModel(const std::string& path);

namespace detail {
/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, initial and final xor 0xFFFFFFFF), as zlib's crc32.
std::uint32_t crc32(const unsigned char* data, std::size_t size);
/// Recomputes both checksums of a buffer laid out as a CFL file (no-op when it is shorter than the header).
/// Lets tests and fuzzers reach the checks behind the checksum with hand-edited files.
void resealCflBuffer(unsigned char* data, std::size_t size);
}  // namespace detail

}  // namespace cfl
