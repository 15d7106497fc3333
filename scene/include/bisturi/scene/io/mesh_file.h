#pragma once
// Mesh files in and out: OBJ, PLY (ascii and binary), STL (ascii and binary) and OFF are read
// into a plain polygon list, exactly as the file holds it (no welding, no triangulation, no
// reordering); OBJ and PLY are written. Building a solid from the list is a later stage.
//
// Reading rules, the same for every format:
// - Element numbers in messages (vertex 12, face 3) are 0-based positions in the result; OBJ
//   indices are quoted as written in the file.
// - Faces with 1 or 2 indices are kept as read (the construction stage drops and counts them);
//   a face with no index is an error.
// - Every problem throws InputError naming the file, the place (`line N` for text, `byte N` for
//   binary data) and the element: a truncated or corrupt file, an index out of range, a NaN or
//   infinite coordinate, a count the data does not hold, an empty file. Nothing partial is
//   returned, and no count read from a file is trusted before it is checked against the bytes
//   that follow it.
// - The one leniency: a PLY header line of unknown kind (free text an old exporter wrote without
//   `comment`) is skipped and named in MeshFile::warnings, as rply, assimp and MeshLab do.

#include <cstddef>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "bisturi/scene/oriented_builder.h"

namespace bisturi {

enum class MeshFormat { Obj, Ply, Stl, Off };

struct MeshFile {
  /// Positions (double) and polygons in file order. OBJ face indices are resolved (negative,
  /// relative ones too) to 0-based positions.
  PolygonMesh polygons;
  /// False for STL: every triangle brings its own three positions (a soup, no shared vertices).
  bool has_vertex_list = true;
  MeshFormat format = MeshFormat::Obj;
  std::size_t source_bytes = 0;
  /// What was skipped because real tools skip it, one message each ("file: line N: ..."): PLY
  /// header lines of unknown kind. Callers show them; nothing else is lenient.
  std::vector<std::string> warnings;
};

struct ReadOptions {
  /// Called with (bytes parsed, total bytes) about every MiB of input and once at the end.
  std::function<void(std::size_t done_bytes, std::size_t total_bytes)> progress;
};

/// The format named by the extension (.obj .ply .stl .off, any case); InputError for others.
MeshFormat format_from_path(const std::filesystem::path& file);

/// Reads the whole file into memory and parses it in the format its extension names.
MeshFile read_mesh(const std::filesystem::path& file, const ReadOptions& options = {});

/// Parses a file image already in memory; `name_for_errors` starts every error message.
MeshFile read_mesh_from_memory(std::span<const std::byte> data, MeshFormat format,
                               const std::string& name_for_errors, const ReadOptions& options = {});

enum class PlyEncoding { Ascii, BinaryLittleEndian, BinaryBigEndian };

/// Writers store doubles in their shortest exact decimal form (text) or as float64 (binary), so
/// reading a written file gives the same bits back. Both refuse (InputError) a mesh with an
/// index out of range, an empty face or a non-finite coordinate; a failed write throws
/// SceneError naming the file.

/// `v x y z` lines, then `f` lines with 1-based indices.
void write_obj(const std::filesystem::path& file, const PolygonMesh& mesh);

/// Vertex element with double x y z; face element with `list uchar int vertex_indices` (uint
/// count when a face has more than 255 corners, uint indices past 2^31 - 1 vertices).
void write_ply(const std::filesystem::path& file, const PolygonMesh& mesh,
               PlyEncoding encoding = PlyEncoding::BinaryLittleEndian);

}  // namespace bisturi
