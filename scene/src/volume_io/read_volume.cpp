// read_volume: the reader by extension, or a DICOM series for a folder.

#include <system_error>

#include "../io/file_io.h"
#include "bisturi/scene/errors.h"
#include "readers.h"
#include "volume_common.h"

namespace bisturi {

VolumeFile read_volume_file(const std::filesystem::path& file_or_dir,
                            const VolumeReadOptions& options) {
  const std::string name = file_or_dir.string();
  std::error_code ec;
  if (std::filesystem::is_directory(file_or_dir, ec)) {
    return volume_io::read_dicom_folder(file_or_dir, options);
  }
  using volume_io::ends_with_icase;
  if (ends_with_icase(name, ".nrrd") || ends_with_icase(name, ".nhdr")) {
    const mesh_io::FileBytes bytes = mesh_io::read_file(file_or_dir);
    std::filesystem::path dir = file_or_dir.parent_path();
    if (dir.empty()) dir = ".";
    return volume_io::parse_nrrd(bytes.bytes(), name, options, dir);
  }
  if (ends_with_icase(name, ".nii") || ends_with_icase(name, ".nii.gz")) {
    const mesh_io::FileBytes bytes = mesh_io::read_file(file_or_dir);
    return volume_io::parse_nifti(bytes.bytes(), name, options);
  }
  throw InputError(name +
                   ": unknown volume format (expected .nrrd, .nhdr, .nii, .nii.gz or a "
                   "folder of DICOM slices)");
}

Volume read_volume(const std::filesystem::path& file_or_dir, const VolumeReadOptions& options) {
  return read_volume_file(file_or_dir, options).volume;
}

Volume read_dicom_series(const std::filesystem::path& dir, const VolumeReadOptions& options) {
  return volume_io::read_dicom_folder(dir, options).volume;
}

}  // namespace bisturi
