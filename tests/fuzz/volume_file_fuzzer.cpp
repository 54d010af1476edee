// libFuzzer target for the offline volume readers (client-cli/volume_file.hpp). Byte 0
// picks the reader; the rest is the input:
//   0  text volume from memory (parse_text_volume)
//   1  text volume from a file (read_volume without dims)
//   2  raw volume, dims from the next 3 bytes (each 0..255), samples after them
//   3  raw volume, dims from the next 12 bytes (3 int32 little-endian: huge and negative
//      ones included), samples after them
//   4  --dims text (parse_dims)
//   5  NIfTI-1 from memory (parse_nifti: plain or gzip)
//   6  NRRD from memory (parse_nrrd; inputs naming a detached data file are skipped, so
//      that the fuzzer reads no file of this machine)
// Files are a memfd reached through /proc/self/fd, so the readers' own file code runs
// without touching the disk. Every refusal is a VolumeError; a header may never make a
// reader allocate more than its input can fill (scripts/fuzz.sh caps the memory).
#include <sys/mman.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>

#include "client-cli/nifti_file.hpp"
#include "client-cli/nrrd_file.hpp"
#include "client-cli/volume_file.hpp"

namespace {

using vox::cli::VolumeError;

// A file holding `bytes`; its path stays the same for the whole run.
const std::string& file_of(std::string_view bytes) {
  static const int fd = memfd_create("volume_file_fuzzer", 0);
  static const std::string path = "/proc/self/fd/" + std::to_string(fd);
  if (fd < 0 || ftruncate(fd, 0) != 0 ||
      pwrite(fd, bytes.data(), bytes.size(), 0) != static_cast<ssize_t>(bytes.size())) {
    std::abort();
  }
  return path;
}

int32_t int32_at(const uint8_t* p) {
  return static_cast<int32_t>(static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
                              static_cast<uint32_t>(p[2]) << 16 |
                              static_cast<uint32_t>(p[3]) << 24);
}

// Whether an NRRD header may name a detached data file ("data file:", "datafile:", any case).
bool names_a_data_file(std::string_view input) {
  std::string lower(input.substr(0, vox::cli::kMaxNrrdHeaderBytes + 1));
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower.find("data file") != std::string::npos ||
         lower.find("datafile") != std::string::npos;
}

void check_volume(const vox::mesh::Volume& v) {
  size_t n = 1;
  for (int d : v.dims) {
    if (d < 2) std::abort();
    n *= static_cast<size_t>(d);
  }
  if (n != v.values.size()) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  std::string_view input(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    switch (data[0] % 7) {
      case 0:
        check_volume(vox::cli::parse_text_volume(input, "fuzz.txt"));
        break;
      case 1:
        check_volume(vox::cli::read_volume(file_of(input), std::nullopt));
        break;
      case 2:
      case 3: {
        const size_t header = data[0] % 7 == 2 ? 3 : 12;
        if (input.size() < header) return 0;
        std::array<int, 3> dims{};
        for (int a = 0; a < 3; ++a) {
          dims[a] = header == 3 ? data[1 + a] : int32_at(data + 1 + 4 * a);
        }
        input.remove_prefix(header);
        const auto volume = vox::cli::read_volume(file_of(input), dims);
        check_volume(volume);
        if (volume.dims != dims) std::abort();
        break;
      }
      case 4:
        (void)vox::cli::parse_dims(std::string(input));
        break;
      case 5:
        check_volume(vox::cli::parse_nifti(
                         {reinterpret_cast<const uint8_t*>(input.data()), input.size()}, "fuzz.nii")
                         .volume);
        break;
      case 6:
        if (names_a_data_file(input)) return 0;
        check_volume(
            vox::cli::parse_nrrd({reinterpret_cast<const uint8_t*>(input.data()), input.size()},
                                 "fuzz.nrrd")
                .volume);
        break;
    }
  } catch (const VolumeError&) {
    // refused, with a message: what the command prints
  }
  return 0;
}
