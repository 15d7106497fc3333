#pragma once
// Volume files in and out: NRRD (.nrrd, .nhdr + detached data), NIfTI-1 (.nii, .nii.gz) and
// DICOM series (a folder of slices, read with GDCM), all into the LPS millimetre world frame of
// volume.h.
//
// Reading rules, the same for every format:
// - Values are the stored samples as float, after the file's rescale where it has one (NIfTI
//   scl_slope / scl_inter, DICOM RescaleSlope / RescaleIntercept: CT comes out in Hounsfield
//   units). NRRD has no rescale.
// - Geometry: NRRD `space` (RAS, LAS, LPS, spelled either way) and NIfTI's RAS world are turned
//   into LPS; spacing is the length of each index axis' world step, direction its unit vector
//   (columns, orthonormal: nearly orthogonal axes are straightened, sheared grids are refused).
// - Every problem throws InputError whose message starts with the file (for a series: the slice
//   file, or the folder) and says the place (`byte N` where it helps) and the reason: truncated
//   data, a header whose sizes the data does not hold or whose size product overflows, an
//   unknown or unsupported type or encoding, zero, negative or NaN spacing, slices of mixed size,
//   spacing or orientation, a missing slice. Nothing partial is returned, and no size read from a
//   file is trusted (nothing is allocated for it) before it is checked against the bytes that
//   hold the data.

#include <cstddef>
#include <filesystem>
#include <functional>
#include <span>
#include <string>

#include "bisturi/scene/volume/volume.h"

namespace bisturi {

enum class VolumeFormat { Nrrd, Nifti, DicomSeries };

struct VolumeReadOptions {
  /// Called with (work done, total work) now and then and once at the end: sample bytes
  /// converted for NRRD and NIfTI, slice files for a DICOM series.
  std::function<void(std::size_t done, std::size_t total)> progress;
  /// DICOM: the SeriesInstanceUID to read when the folder holds several series (empty: the
  /// folder must hold exactly one, otherwise the error lists them).
  std::string series_uid;
};

/// A volume with what the file said about its storage (for `bisturi volume info`).
struct VolumeFile {
  Volume volume;
  VolumeFormat format = VolumeFormat::Nrrd;
  /// The stored sample type: "int8" .. "uint64", "float32", "float64".
  std::string stored_type;
  /// Whether a rescale (slope != 1 or intercept != 0) was applied to the stored values.
  bool rescaled = false;
};

/// Reads a volume: .nrrd / .nhdr, .nii / .nii.gz by extension (any case), a folder as a DICOM
/// series. InputError for other extensions.
Volume read_volume(const std::filesystem::path& file_or_dir, const VolumeReadOptions& options = {});
VolumeFile read_volume_file(const std::filesystem::path& file_or_dir,
                            const VolumeReadOptions& options = {});

/// A NRRD file image in memory; `name_for_errors` starts every message. A `data file` field is
/// resolved against `data_dir`; with an empty `data_dir` detached data is refused (InputError).
Volume read_nrrd_from_memory(std::span<const std::byte> data, const std::string& name_for_errors,
                             const VolumeReadOptions& options = {},
                             const std::filesystem::path& data_dir = {});

/// A NIfTI-1 single-file image (`n+1`) in memory, plain or gzip-compressed (.nii.gz).
Volume read_nifti_from_memory(std::span<const std::byte> data, const std::string& name_for_errors,
                              const VolumeReadOptions& options = {});

/// The DICOM image slices of one folder, as one volume (see VolumeReadOptions::series_uid).
Volume read_dicom_series(const std::filesystem::path& dir, const VolumeReadOptions& options = {});

enum class NrrdEncoding { Raw, Gzip };

/// Writers store float32 samples (bit-exact on reading back) with the geometry in the file's own
/// frame. Both refuse (InputError) a volume whose geometry is not valid (sizes < 1, spacing not
/// finite and positive, direction not orthonormal) or whose value count does not match; a failed
/// write throws SceneError naming the file.

/// NRRD0004, `space: left-posterior-superior`, `space directions`, `space origin`, little endian.
void write_nrrd(const std::filesystem::path& file, const Volume& volume,
                NrrdEncoding encoding = NrrdEncoding::Raw);

/// NIfTI-1 single file, gzip-compressed when the name ends in .gz; float32, units mm, sform and
/// qform (code 1, scanner) from the geometry turned into RAS. NIfTI stores the geometry as
/// float32, so it comes back to within float precision.
void write_nifti(const std::filesystem::path& file, const Volume& volume);

struct ValueRange {
  /// NaN when the volume holds no finite value.
  float min = 0.0f;
  float max = 0.0f;
  std::size_t finite_count = 0;
};

/// Minimum and maximum over the finite values.
ValueRange value_range(const Volume& volume);

/// "NRRD", "NIfTI-1", "DICOM series".
const char* to_string(VolumeFormat format);

}  // namespace bisturi
