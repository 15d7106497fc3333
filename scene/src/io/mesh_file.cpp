#include "bisturi/scene/io/mesh_file.h"

#include <cctype>

#include "bisturi/scene/errors.h"
#include "file_io.h"
#include "parse_errors.h"
#include "readers.h"

namespace bisturi {

MeshFormat format_from_path(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  for (char& c : ext)
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".ply") return MeshFormat::Ply;
  if (ext == ".stl") return MeshFormat::Stl;
  if (ext == ".off") return MeshFormat::Off;
  throw InputError(mesh_io::cat(file.string(), ": unknown mesh file extension ",
                                mesh_io::quoted(ext), " (expected .obj, .ply, .stl or .off)"));
}

MeshFile read_mesh(const std::filesystem::path& file, const ReadOptions& options) {
  const MeshFormat format = format_from_path(file);
  const mesh_io::FileBytes bytes = mesh_io::read_file(file);
  return read_mesh_from_memory(bytes.bytes(), format, file.string(), options);
}

MeshFile read_mesh_from_memory(std::span<const std::byte> data, MeshFormat format,
                               const std::string& name_for_errors, const ReadOptions& options) {
  switch (format) {
    case MeshFormat::Obj:
      return mesh_io::read_obj(data, name_for_errors, options);
    case MeshFormat::Ply:
      return mesh_io::read_ply(data, name_for_errors, options);
    case MeshFormat::Stl:
      return mesh_io::read_stl(data, name_for_errors, options);
    case MeshFormat::Off:
      return mesh_io::read_off(data, name_for_errors, options);
  }
  throw InputError(name_for_errors + ": unknown mesh format");
}

}  // namespace bisturi
