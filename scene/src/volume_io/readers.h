#pragma once
// The readers behind volume_io.h, each returning what the file said about its storage too.

#include <cstddef>
#include <filesystem>
#include <span>
#include <string>

#include "bisturi/scene/volume/volume_io.h"

namespace bisturi::volume_io {

/// `data_dir` empty: a `data file` field is refused.
VolumeFile parse_nrrd(std::span<const std::byte> data, const std::string& name,
                      const VolumeReadOptions& options, const std::filesystem::path& data_dir);

/// Plain or gzip-compressed single-file NIfTI-1.
VolumeFile parse_nifti(std::span<const std::byte> data, const std::string& name,
                       const VolumeReadOptions& options);

VolumeFile read_dicom_folder(const std::filesystem::path& dir, const VolumeReadOptions& options);

}  // namespace bisturi::volume_io
