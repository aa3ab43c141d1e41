#pragma once
/// @file
/// Saving and loading a built CflModel, so that the expensive precomputation runs once.
///
/// The format (full description, with a byte map, in docs/cfl_file_format.md), version 4:
///
///     offset  size  field
///          0     8  magic 0x89 'C' 'F' 'L' '\r' '\n' 0x1A '\n'  (PNG-style: catches text-mode mangling)
///          8     4  endianness marker 0x01020304, stored as bytes 04 03 02 01
///         12     4  format version (4)
///         16     8  payload size P in bytes
///         24     4  CRC-32 (IEEE 802.3, zlib's crc32) of the P payload bytes
///         28     4  CRC-32 of bytes 0..27 (the header)
///         32     P  payload: sections, each a 4-byte ASCII tag, a u32 zero, a u64 length L and L bytes
///
/// Every integer, float and double is little-endian whatever the host (floats and doubles as their IEEE-754
/// bit patterns), so files move between machines. The sections, in this order, are MESH (vertices,
/// triangles), TREE (the region tree's origin, root_size, root_dims and max_depth, padding, topology flag,
/// corner_distance_unit), NODE (RegionTree::nodes), LEAF (per leaf: its list, lower bound and eight 16-bit
/// corner distances), LIST
/// (list_offsets, list_triangles), LBND (list_entry_bounds) and STAT (statistics, leaves_per_depth and the
/// coarsened flag included). Sections with an unknown tag are skipped, so a later writer can add data that
/// old readers ignore; a change of meaning bumps the version instead. The Bvh and triangle corners are not
/// stored: loading rebuilds them with makeMeshModel, which is deterministic, so a loaded model answers every
/// query bit-identically to the model that was saved.
///
/// Versions 1 and 2 held a uniform voxel grid, version 3 float corner distances; they are refused with a
/// message asking for a rebuild (the regions are derived data, and `cfl build` makes them again from the
/// mesh).

#include "cfl/cfl_model.h"

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace cfl {

/// The version written and read by this library.
constexpr std::uint32_t kCflFileVersion = 4;

/// The model as the bytes of a version-4 file, in memory (writeCflModel and saveCflModel write the same bytes
/// without holding them). O(model size); thread-safe (reads `model` only).
/// Throws cfl::Error when the mesh fails validateMesh, or (the message starting "cannot save CFL model: ")
/// when the model breaks an invariant that the loader checks, so that no file is written that the loader
/// would refuse: e.g. a list holding a triangle id out of range, or a node pointing back.
std::vector<unsigned char> serializeCflModel(const CflModel& model);

/// Parses the bytes of a file written by serializeCflModel. Everything is checked before it is used, so
/// that no file, damaged or hostile, makes a later query crash, hang or read out of bounds:
/// - the size, magic, endianness marker, version (versions 1 to 3 are refused: "<name>: a version-2 CFL
///   file (uniform grid) from an earlier cfl: rebuild it with `cfl build`") and both checksums;
/// - every count against the bytes that remain, before anything is allocated;
/// - the mesh (validateMesh);
/// - the root grid: finite origin and far corner, finite positive root_size, root_dims >= 1 whose product
///   (checked by division, so it cannot overflow) does not exceed the node count, max_depth in [0, 24],
///   corner_distance_unit a power of two in [2^-16, 1];
/// - the tree: every node with children points forward (past itself, past the root cells, with all eight
///   children inside the array), so that no walk loops; every node but the roots is the child of exactly
///   one parent; no cell is deeper than max_depth, which is the deepest leaf's depth; every leaf index is
///   in range and named by exactly one node;
/// - the leaves: list index in range or RegionTree::kNoList (no list: queries use the Bvh there), lower
///   bound finite and >= 0;
/// - the lists: offsets from 0 to the entry count, increasing, no list empty, triangle ids in range, each
///   list sorted by (entry bound, id);
/// - padding finite and >= 1, statistics finite, non-negative and consistent with the tree (leaf count,
///   leaves without a list, leaves per depth, distinct lists).
/// Any failure throws cfl::Error whose message starts with `name_for_errors` (usually the file path) and
/// says what is wrong, e.g.
/// "robot.cfl: checksum mismatch (payload CRC-32 is 0x1c291ca3, header says 0x5d0f4e12): the file is corrupt".
///
/// A checksum guards against accidental corruption only: a file forged to pass it with wrong lists (but valid
/// structure) would load and give wrong distances. Load only files you or your tools wrote.
/// Time and extra memory are linear in `size`; the Bvh is rebuilt, O(n log n) in the triangle count.
CflModel deserializeCflModel(const unsigned char* data, std::size_t size, const std::string& name_for_errors);

/// Writes the bytes of serializeCflModel(model) to `stream`, in order and without seeking (a pipe or socket
/// will do), and without holding the file in memory: extra memory is a 64 KiB buffer plus the validation's
/// O(node count) scratch. The model is read twice, first for the payload checksum that the header holds, so
/// it must not change meanwhile; concurrent readers are fine. Time is linear in the model size.
/// Throws cfl::Error, before writing anything, when the model is refused as by serializeCflModel, or
/// ("writing a CFL model: the stream failed after N of M bytes") when a write fails; the stream then holds
/// a truncated file, which the loader refuses.
void writeCflModel(const CflModel& model, std::ostream& stream);

/// Writes `model` to `path` (replacing it) through a temporary file in the same directory that is renamed
/// into place, so readers never see a half-written file; as writeCflModel, the file is never held in memory.
/// Throws cfl::Error when the model is refused (as by serializeCflModel; no file is created) or naming the
/// path when the file cannot be written.
void saveCflModel(const CflModel& model, const std::string& path);

/// Reads a model saved by saveCflModel. Throws cfl::Error naming `path` when the file cannot be read or is
/// not a valid version-4 CFL file (see deserializeCflModel for what is checked).
CflModel loadCflModel(const std::string& path);

namespace detail {
/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, initial and final xor 0xFFFFFFFF): zlib's crc32,
/// for any size (zlib takes 32-bit lengths).
std::uint32_t crc32(const unsigned char* data, std::size_t size);
/// Recomputes both checksums of a buffer laid out as a CFL file (no-op when it is shorter than the header).
/// Lets tests and fuzzers reach the checks behind the checksum with hand-edited files.
void resealCflBuffer(unsigned char* data, std::size_t size);
}  // namespace detail

}  // namespace cfl
