// The scanner volume readers (NIfTI-1, NRRD), and `voxel-cli mesh` on them, on small files
// written here: every sample type in both byte orders, gzip, scaling, spacing, detached
// data, and each kind of bad file refused with a one-line message before anything large
// is allocated.
#include <gtest/gtest.h>
#include <zlib.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>

#include "client-cli/commands.hpp"
#include "client-cli/nifti_file.hpp"
#include "client-cli/nrrd_file.hpp"
#include "client-cli/volume_file.hpp"
#include "tests/alloc_counter.hpp"
#include "tests/temp_dir.hpp"

namespace vox::cli {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<uint8_t>;

constexpr std::array<int, 3> kDims{3, 4, 5};
constexpr SampleType kTypes[] = {SampleType::kU8,  SampleType::kI8,  SampleType::kU16,
                                 SampleType::kI16, SampleType::kU32, SampleType::kI32,
                                 SampleType::kF32, SampleType::kF64};

bool is_signed(SampleType t) {
  return t != SampleType::kU8 && t != SampleType::kU16 && t != SampleType::kU32;
}

// Sample i of the test volume: small integers, negative ones for signed types.
double value_at(size_t i, SampleType t) {
  const double v = static_cast<double>(i % 11);
  return is_signed(t) ? v - 5 : v;
}

void append_sample(Bytes& out, double v, SampleType t, bool big_endian) {
  uint8_t b[8];
  size_t n = sample_size(t);
  switch (t) {
    case SampleType::kU8:
      b[0] = static_cast<uint8_t>(v);
      break;
    case SampleType::kI8:
      b[0] = static_cast<uint8_t>(static_cast<int8_t>(v));
      break;
    case SampleType::kU16: {
      const uint16_t u = static_cast<uint16_t>(v);
      std::memcpy(b, &u, 2);
      break;
    }
    case SampleType::kI16: {
      const int16_t u = static_cast<int16_t>(v);
      std::memcpy(b, &u, 2);
      break;
    }
    case SampleType::kU32: {
      const uint32_t u = static_cast<uint32_t>(v);
      std::memcpy(b, &u, 4);
      break;
    }
    case SampleType::kI32: {
      const int32_t u = static_cast<int32_t>(v);
      std::memcpy(b, &u, 4);
      break;
    }
    case SampleType::kF32: {
      const float u = static_cast<float>(v);
      std::memcpy(b, &u, 4);
      break;
    }
    case SampleType::kF64:
      std::memcpy(b, &v, 8);
      break;
  }
  const bool swap = big_endian == (std::endian::native == std::endian::little);
  for (size_t i = 0; i < n; ++i) out.push_back(b[swap ? n - 1 - i : i]);
}

Bytes samples(SampleType t, bool big_endian, std::array<int, 3> dims = kDims) {
  Bytes out;
  for (size_t i = 0; i < volume_sample_count(dims); ++i)
    append_sample(out, value_at(i, t), t, big_endian);
  return out;
}

Bytes gzip(const Bytes& in) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY), Z_OK);
  Bytes out(deflateBound(&z, in.size()) + 64);
  z.next_in = const_cast<Bytef*>(in.data());
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = out.data();
  z.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

int16_t nifti_code(SampleType t) {
  switch (t) {
    case SampleType::kU8:
      return 2;
    case SampleType::kI16:
      return 4;
    case SampleType::kI32:
      return 8;
    case SampleType::kF32:
      return 16;
    case SampleType::kF64:
      return 64;
    case SampleType::kI8:
      return 256;
    case SampleType::kU16:
      return 512;
    case SampleType::kU32:
      return 768;
  }
  return 0;
}

struct NiftiSpec {
  SampleType type = SampleType::kI16;
  bool big_endian = false;
  std::array<int16_t, 8> dim{3, kDims[0], kDims[1], kDims[2], 1, 1, 1, 1};
  std::array<float, 3> pixdim{1, 1, 1};
  float slope = 0, inter = 0;
  float vox_offset = 352;
  const char* magic = "n+1";
  int32_t sizeof_hdr = 348;
  int16_t bitpix = 0;  // 0: the type's
};

// A header field in the file's byte order.
template <class T>
void put_field(Bytes& h, size_t at, T v, bool big_endian) {
  uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof v);
  if (big_endian == (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof v);
  std::memcpy(h.data() + at, b, sizeof v);
}

Bytes nifti_file(const NiftiSpec& s, const Bytes& data) {
  Bytes f(352, 0);
  put_field(f, 0, s.sizeof_hdr, s.big_endian);
  for (int i = 0; i < 8; ++i) put_field(f, 40 + 2 * i, s.dim[i], s.big_endian);
  put_field(f, 70, nifti_code(s.type), s.big_endian);
  put_field(f, 72, static_cast<int16_t>(s.bitpix ? s.bitpix : 8 * sample_size(s.type)),
            s.big_endian);
  for (int a = 0; a < 3; ++a) put_field(f, 76 + 4 * (1 + a), s.pixdim[a], s.big_endian);
  put_field(f, 108, s.vox_offset, s.big_endian);
  put_field(f, 112, s.slope, s.big_endian);
  put_field(f, 116, s.inter, s.big_endian);
  std::memcpy(f.data() + 344, s.magic, std::strlen(s.magic) + 1);
  f.insert(f.end(), data.begin(), data.end());
  return f;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const VolumeError& e) {
    return e.what();
  }
  return "(no error)";
}

class VolumeFormats : public ::testing::Test {
 protected:
  std::string write(const std::string& name, const Bytes& bytes) const {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()),
               static_cast<std::streamsize>(bytes.size()));
    return p;
  }
  std::string write(const std::string& name, const std::string& text) const {
    return write(name, Bytes(text.begin(), text.end()));
  }
  test::TempDir dir_{"formats"};
};

void expect_test_values(const LoadedVolume& v, SampleType t, double slope = 1, double inter = 0) {
  ASSERT_EQ(v.volume.dims, kDims);
  ASSERT_EQ(v.volume.values.size(), volume_sample_count(kDims));
  for (size_t i = 0; i < v.volume.values.size(); ++i)
    ASSERT_FLOAT_EQ(v.volume.values[i], static_cast<float>(value_at(i, t) * slope + inter)) << i;
}

TEST_F(VolumeFormats, NiftiEveryTypeInBothByteOrdersPlainAndGzip) {
  for (SampleType t : kTypes) {
    for (bool big : {false, true}) {
      SCOPED_TRACE(std::string(sample_type_name(t)) + (big ? " big-endian" : " little-endian"));
      NiftiSpec spec;
      spec.type = t;
      spec.big_endian = big;
      const Bytes file = nifti_file(spec, samples(t, big));
      expect_test_values(read_nifti(write("v.nii", file)), t);
      expect_test_values(read_nifti(write("v.nii.gz", gzip(file))), t);
      expect_test_values(load_volume(write("w.nii.gz", gzip(file)), std::nullopt), t);
    }
  }
}

TEST_F(VolumeFormats, NiftiSlopeAndInterceptScaleTheSamplesAndPixdimIsTheSpacing) {
  NiftiSpec spec;
  spec.slope = 2.5f;
  spec.inter = -1.0f;
  spec.pixdim = {0.5f, 0.75f, 2.0f};
  spec.vox_offset = 368;  // 16 bytes of extension after the header
  Bytes data(16, 0xAB);
  const Bytes s = samples(spec.type, false);
  data.insert(data.end(), s.begin(), s.end());
  const LoadedVolume v = read_nifti(write("v.nii", nifti_file(spec, data)));
  expect_test_values(v, spec.type, 2.5, -1.0);
  ASSERT_TRUE(v.spacing);
  EXPECT_EQ(*v.spacing, (std::array<float, 3>{0.5f, 0.75f, 2.0f}));
}

TEST_F(VolumeFormats, NiftiBadFilesAreRefusedWithTheirReason) {
  const Bytes good = samples(SampleType::kI16, false);
  auto refused = [&](const NiftiSpec& spec, const Bytes& data, const std::string& expect) {
    SCOPED_TRACE(expect);
    const std::string msg =
        message_of([&] { read_nifti(write("bad.nii", nifti_file(spec, data))); });
    EXPECT_NE(msg.find(expect), std::string::npos) << msg;
    EXPECT_NE(msg.find("bad.nii"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  };
  NiftiSpec s;
  refused(s, Bytes(good.begin(), good.end() - 1), "declares 120 bytes");  // truncated data
  s.dim = {3, 32767, 32767, 32767, 1, 1, 1, 1};
  refused(s, good, "too large");  // dims whose product overflows the limit
  s = {};
  s.dim = {3, -4, 4, 5, 1, 1, 1, 1};
  refused(s, good, "at least 2");
  s = {};
  s.dim = {4, 3, 4, 5, 2, 1, 1, 1};
  refused(s, good, "only one 3-D volume");
  s = {};
  s.dim = {2, 3, 4, 1, 1, 1, 1, 1};
  refused(s, good, "a 3-D volume is needed");
  s = {};
  s.type = SampleType::kI16;
  s.bitpix = 8;
  refused(s, good, "bitpix 8 does not match");
  s = {};
  s.sizeof_hdr = 540;
  refused(s, good, "NIfTI-2");
  s = {};
  s.sizeof_hdr = 1234;
  refused(s, good, "not a NIfTI-1 file");
  s = {};
  s.magic = "ni1";
  refused(s, good, ".hdr/.img pair");
  s = {};
  s.vox_offset = -5;
  refused(s, good, "vox_offset");
  {  // an unknown datatype code
    Bytes f = nifti_file(NiftiSpec{}, good);
    put_field(f, 70, int16_t{1536}, false);  // float128
    const std::string msg = message_of([&] { read_nifti(write("bad.nii", f)); });
    EXPECT_NE(msg.find("datatype 1536 is not supported"), std::string::npos) << msg;
  }
  {  // a header cut short
    const Bytes f = nifti_file(NiftiSpec{}, good);
    const std::string msg =
        message_of([&] { read_nifti(write("bad.nii", Bytes(f.begin(), f.begin() + 100))); });
    EXPECT_NE(msg.find("too short"), std::string::npos) << msg;
  }
  {  // a NaN sample
    NiftiSpec f32;
    f32.type = SampleType::kF32;
    Bytes data = samples(SampleType::kF32, false);
    const float nan = std::nanf("");
    std::memcpy(data.data() + 4 * 7, &nan, 4);
    const std::string msg =
        message_of([&] { read_nifti(write("bad.nii", nifti_file(f32, data))); });
    EXPECT_NE(msg.find("sample 7 is not finite"), std::string::npos) << msg;
  }
}

TEST_F(VolumeFormats, GzipFilesThatAreCutShortCorruptOrBombsAreRefused) {
  const Bytes file = nifti_file(NiftiSpec{}, samples(SampleType::kI16, false));
  const Bytes gz = gzip(file);
  std::string msg = message_of(
      [&] { read_nifti(write("cut.nii.gz", Bytes(gz.begin(), gz.begin() + gz.size() / 2))); });
  EXPECT_NE(msg.find("gzip data end in the"), std::string::npos) << msg;
  Bytes corrupt = gz;
  for (size_t i = 12; i < corrupt.size() - 8; ++i) corrupt[i] ^= 0x5A;
  msg = message_of([&] { read_nifti(write("corrupt.nii.gz", corrupt)); });
  EXPECT_NE(msg.find("gzip"), std::string::npos) << msg;
  // A bomb: a few hundred compressed bytes declaring a 1000^3 uint8 volume. Refused from
  // the sizes alone (the test's memory limit under ASan would not survive allocating it).
  NiftiSpec bomb;
  bomb.type = SampleType::kU8;
  bomb.dim = {3, 1000, 1000, 1000, 1, 1, 1, 1};
  const Bytes bomb_file = gzip(nifti_file(bomb, Bytes(1 << 16, 0)));
  msg = message_of([&] { read_nifti(write("bomb.nii.gz", bomb_file)); });
  EXPECT_NE(msg.find("more than"), std::string::npos) << msg;
  EXPECT_NE(msg.find("bytes of gzip data can hold"), std::string::npos) << msg;
}

// A review found: the samples' floats were allocated (and zeroed) for everything the
// header declared before one byte was decompressed: a 128 KiB file reached 529 MiB.
TEST_F(VolumeFormats, AGzipStreamShorterThanItsHeaderCostsOnlyWhatItHolds) {
  NiftiSpec spec;
  spec.type = SampleType::kU8;
  spec.dim = {3, 400, 400, 400, 1, 1, 1, 1};  // 64 M samples: 256 MiB of floats
  Bytes data(1 << 20);  // random: it does not compress, so the size check lets it through
  std::mt19937 rng(5);
  for (uint8_t& b : data) b = static_cast<uint8_t>(rng());
  const std::string file = write("short.nii.gz", gzip(nifti_file(spec, data)));
  const size_t before = test::bytes_allocated_on_this_thread();
  const std::string msg = message_of([&] { read_nifti(file); });
  EXPECT_NE(msg.find("gzip data end in the samples, after 1048928 decompressed bytes"),
            std::string::npos)
      << msg;
  EXPECT_LT(test::bytes_allocated_on_this_thread() - before, size_t{32} << 20);
}

std::string nrrd_type_name(SampleType t) {
  switch (t) {
    case SampleType::kU8:
      return "uchar";
    case SampleType::kI8:
      return "signed char";
    case SampleType::kU16:
      return "unsigned short";
    case SampleType::kI16:
      return "short";
    case SampleType::kU32:
      return "uint";
    case SampleType::kI32:
      return "int32";
    case SampleType::kF32:
      return "float";
    case SampleType::kF64:
      return "double";
  }
  return "";
}

std::string nrrd_header(SampleType t, const std::string& encoding, bool big,
                        const std::string& extra = "") {
  return "NRRD0004\n# written by volume_formats_test\ntype: " + nrrd_type_name(t) +
         "\ndimension: 3\nsizes: 3 4 5\nencoding: " + encoding +
         "\nendian: " + (big ? "big" : "little") + "\n" + extra + "\n";
}

Bytes concat(const std::string& header, const Bytes& data) {
  Bytes out(header.begin(), header.end());
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

TEST_F(VolumeFormats, NrrdRepeatedFieldsAndControlCharactersInNamesAreRefused) {
  const Bytes data = samples(SampleType::kU8, false);
  std::string msg = message_of([&] {
    read_nrrd(write("r.nrrd",
                    concat(nrrd_header(SampleType::kU8, "raw", false, "sizes: 3 4 5\n"), data)));
  });
  EXPECT_NE(msg.find("NRRD field 'sizes' appears twice"), std::string::npos) << msg;
  msg = message_of([&] {
    read_nrrd(
        write("c.nhdr", nrrd_header(SampleType::kU8, "raw", false, "data file: x\x1b[2Kok\n")));
  });
  EXPECT_NE(msg.find("has control characters"), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\x1b'), std::string::npos) << msg;
}

TEST_F(VolumeFormats, ANiftiOrNrrdFileUnderAnotherNameIsKnownByItsFirstBytes) {
  const Bytes nrrd =
      concat(nrrd_header(SampleType::kI16, "raw", false), samples(SampleType::kI16, false));
  expect_test_values(load_volume(write("scan.bin", nrrd), std::nullopt), SampleType::kI16);
  const Bytes nii = nifti_file(NiftiSpec{}, samples(SampleType::kI16, false));
  expect_test_values(load_volume(write("scan.dat", gzip(nii)), std::nullopt), SampleType::kI16);
  expect_test_values(load_volume(write("scan.img", nii), std::nullopt), SampleType::kI16);
}

TEST_F(VolumeFormats, NrrdEveryTypeInBothByteOrdersRawGzipAndAscii) {
  for (SampleType t : kTypes) {
    for (bool big : {false, true}) {
      SCOPED_TRACE(std::string(sample_type_name(t)) + (big ? " big-endian" : " little-endian"));
      const Bytes data = samples(t, big);
      expect_test_values(read_nrrd(write("v.nrrd", concat(nrrd_header(t, "raw", big), data))), t);
      expect_test_values(
          read_nrrd(write("g.nrrd", concat(nrrd_header(t, "gzip", big), gzip(data)))), t);
    }
    std::string ascii;
    for (size_t i = 0; i < volume_sample_count(kDims); ++i)
      ascii += std::to_string(value_at(i, t)) + (i % 3 == 2 ? "\n" : " ");
    expect_test_values(read_nrrd(write("a.nrrd", concat(nrrd_header(t, "ascii", false),
                                                        Bytes(ascii.begin(), ascii.end())))),
                       t);
  }
}

TEST_F(VolumeFormats, NrrdSpacingComesFromSpacingsOrSpaceDirections) {
  const Bytes data = samples(SampleType::kU8, false);
  LoadedVolume v = read_nrrd(write(
      "s.nrrd", concat(nrrd_header(SampleType::kU8, "raw", false, "spacings: 0.5 1 2\n"), data)));
  ASSERT_TRUE(v.spacing);
  EXPECT_EQ(*v.spacing, (std::array<float, 3>{0.5f, 1.0f, 2.0f}));
  v = read_nrrd(
      write("d.nrrd", concat(nrrd_header(SampleType::kU8, "raw", false,
                                         "space: left-posterior-superior\n"
                                         "space directions: (0,0.6,0.8) (0,-2,0) (3,0,0)\n"
                                         "space origin: (1,2,3)\n"),
                             data)));
  ASSERT_TRUE(v.spacing);
  EXPECT_FLOAT_EQ((*v.spacing)[0], 1.0f);
  EXPECT_FLOAT_EQ((*v.spacing)[1], 2.0f);
  EXPECT_FLOAT_EQ((*v.spacing)[2], 3.0f);
  v = read_nrrd(write("n.nrrd", concat(nrrd_header(SampleType::kU8, "raw", false), data)));
  EXPECT_FALSE(v.spacing);
}

TEST_F(VolumeFormats, NrrdDetachedDataWithLineAndByteSkip) {
  const Bytes data = samples(SampleType::kI16, true);
  Bytes detached = {'s', 'k', 'i', 'p', '\n', 'x', 'y'};
  detached.insert(detached.end(), data.begin(), data.end());
  write("data.raw", detached);
  const std::string header = nrrd_header(SampleType::kI16, "raw", true,
                                         "data file: data.raw\nline skip: 1\nbyte skip: 2\n");
  expect_test_values(read_nrrd(write("v.nhdr", header.substr(0, header.size() - 1))),
                     SampleType::kI16);
  // byte skip -1: the samples are the file's last bytes.
  const std::string tail =
      nrrd_header(SampleType::kI16, "raw", true, "data file: data.raw\nbyte skip: -1\n");
  expect_test_values(read_nrrd(write("t.nhdr", tail)), SampleType::kI16);
}

TEST_F(VolumeFormats, NrrdBadFilesAreRefusedWithTheirReason) {
  const Bytes data = samples(SampleType::kI16, false);
  auto refused = [&](const Bytes& file, const std::string& expect) {
    SCOPED_TRACE(expect);
    const std::string msg = message_of([&] { read_nrrd(write("bad.nrrd", file)); });
    EXPECT_NE(msg.find(expect), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  };
  refused(concat("NRRD0004\ntype: short\ndimension: 3\nsizes: 3 4 5\nencoding: raw\n\n", data),
          "lacks the endian field");
  refused(concat(nrrd_header(SampleType::kI16, "raw", false), Bytes(data.begin(), data.end() - 2)),
          "declares 120 bytes");
  refused(
      concat("NRRD0004\ntype: long double\ndimension: 3\nsizes: 3 4 5\nencoding: raw\n\n", data),
      "type 'long double' is not supported");
  refused(
      concat("NRRD0004\ntype: short\ndimension: 2\nsizes: 3 4\nencoding: raw\nendian: little\n\n",
             data),
      "dimension is 2");
  refused(
      concat("NRRD0004\ntype: short\ndimension: 3\nsizes: 3 4\nencoding: raw\nendian: little\n\n",
             data),
      "must be 3 numbers");
  refused(concat("NRRD0004\ntype: short\ndimension: 3\nsizes: 3000 4000 5000\nencoding: "
                 "raw\nendian: little\n\n",
                 data),
          "too large");
  refused(
      concat(
          "NRRD0004\ntype: short\ndimension: 3\nsizes: 3 4 5\nencoding: bzip2\nendian: little\n\n",
          data),
      "encoding 'bzip2' is not supported");
  refused(concat("NRRD0004\ntype: short\nsizes: 3 4 5\nencoding: raw\nendian: little\n\n", data),
          "lacks one of");
  refused(concat("PNG\n", data), "not a NRRD file");
  refused(concat("NRRD0004\nthis line has no colon\n\n", data), "not 'field: value'");
  refused(Bytes(80 * 1024, 'a'), "not a NRRD file");
  std::string long_header = "NRRD0004\n";
  while (long_header.size() < 70 * 1024) long_header += "# a long comment line\n";
  refused(concat(long_header, data), "header longer than");
  // A gzip bomb: declares 1000^3 shorts in a few hundred bytes.
  refused(concat("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1000 1000 1000\nencoding: gzip\n\n",
                 gzip(Bytes(4096, 0))),
          "bytes of gzip data can hold");
  // A detached data file that is missing.
  const std::string msg = message_of([&] {
    read_nrrd(
        write("m.nhdr", nrrd_header(SampleType::kI16, "raw", false, "data file: missing.raw\n")));
  });
  EXPECT_NE(msg.find("missing.raw: cannot open"), std::string::npos) << msg;
}

// A ball of radius 5 around (8.3, 7.9, 8.1) in a 17^3 float32 NIfTI volume: value 5 - r.
Bytes ball_nifti(std::array<float, 3> pixdim) {
  NiftiSpec spec;
  spec.type = SampleType::kF32;
  spec.dim = {3, 17, 17, 17, 1, 1, 1, 1};
  spec.pixdim = pixdim;
  Bytes data;
  for (int z = 0; z < 17; ++z)
    for (int y = 0; y < 17; ++y)
      for (int x = 0; x < 17; ++x) {
        const float r =
            std::sqrt((x - 8.3f) * (x - 8.3f) + (y - 7.9f) * (y - 7.9f) + (z - 8.1f) * (z - 8.1f));
        append_sample(data, 5.0f - r, SampleType::kF32, false);
      }
  return nifti_file(spec, data);
}

// The extent of the vertices of a binary PLY written by voxel-cli (positions first).
std::array<float, 3> ply_extent(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  size_t vertices = 0;
  for (std::string line; std::getline(in, line) && line != "end_header";)
    std::sscanf(line.c_str(), "element vertex %zu", &vertices);
  std::array<float, 3> lo{1e30f, 1e30f, 1e30f}, hi{-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < vertices; ++i) {
    float v[6];
    uint8_t material;
    in.read(reinterpret_cast<char*>(v), sizeof v).read(reinterpret_cast<char*>(&material), 1);
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], v[a]);
      hi[a] = std::max(hi[a], v[a]);
    }
  }
  EXPECT_TRUE(in && vertices > 0) << file;
  return {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
}

class CliScanMesh : public VolumeFormats {
 protected:
  int run(std::vector<std::string> args) {
    out_.str("");
    err_.str("");
    return run_cli(args, out_, err_);
  }
  std::ostringstream out_, err_;
};

TEST_F(CliScanMesh, ANiftiVolumeIsMeshedInItsVoxelSpacingUnlessToldOtherwise) {
  const std::string in = write("ball.nii.gz", gzip(ball_nifti({2.0f, 1.0f, 0.5f})));
  const std::string out = (dir_ / "ball.ply").string();
  ASSERT_EQ(run({"mesh", in, "--out", out}), 0) << err_.str();
  std::array<float, 3> e = ply_extent(out);
  EXPECT_NEAR(e[0], 20.0f, 0.5f);  // a diameter of 10 samples
  EXPECT_NEAR(e[1], 10.0f, 0.25f);
  EXPECT_NEAR(e[2], 5.0f, 0.13f);
  ASSERT_EQ(run({"mesh", in, "--out", out, "--no-spacing"}), 0) << err_.str();
  e = ply_extent(out);
  EXPECT_NEAR(e[0], 10.0f, 0.25f);
  EXPECT_NEAR(e[2], 10.0f, 0.25f);
  ASSERT_EQ(run({"mesh", in, "--out", out, "--spacing", "1,3,1"}), 0) << err_.str();
  e = ply_extent(out);
  EXPECT_NEAR(e[1], 30.0f, 0.75f);
  EXPECT_EQ(run({"mesh", in, "--out", out, "--spacing", "1,0,1"}), 2);
  EXPECT_EQ(run({"mesh", in, "--out", out, "--spacing", "1,1,1", "--no-spacing"}), 2);
}

TEST_F(CliScanMesh, AnUnusableSpacingInTheFileIsAnErrorThatNamesTheWayOut) {
  const std::string in = write("flat.nii", ball_nifti({1.0f, 0.0f, 1.0f}));
  const std::string out = (dir_ / "flat.glb").string();
  EXPECT_EQ(run({"mesh", in, "--out", out}), 1);
  EXPECT_NE(err_.str().find("--spacing X,Y,Z or --no-spacing"), std::string::npos) << err_.str();
  EXPECT_FALSE(fs::exists(out));
  ASSERT_EQ(run({"mesh", in, "--out", out, "--no-spacing"}), 0) << err_.str();
  std::ifstream glb(out, std::ios::binary);
  char magic[4] = {};
  glb.read(magic, 4);
  EXPECT_EQ(std::string(magic, 4), "glTF");
}

TEST_F(CliScanMesh, IsoPercentileChoosesTheLevelFromTheSamples) {
  const std::string in = write("ball.nii", ball_nifti({1, 1, 1}));
  const std::string out = (dir_ / "ball.ply").string();
  ASSERT_EQ(run({"mesh", in, "--out", out, "--iso-percentile", "99"}), 0) << err_.str();
  EXPECT_NE(out_.str().find(" at iso "), std::string::npos) << out_.str();
  // The top 1 % of the samples: a small ball around the centre.
  const std::array<float, 3> e = ply_extent(out);
  EXPECT_LT(e[0], 6.0f);
  EXPECT_GT(e[0], 1.0f);
  // The 0th percentile is the smallest sample: everything is at or above it, no surface,
  // and the line says so rather than leaving an empty file unexplained.
  ASSERT_EQ(run({"mesh", in, "--out", out, "--iso-percentile", "0"}), 0) << err_.str();
  EXPECT_NE(out_.str().find("no surface"), std::string::npos) << out_.str();
  EXPECT_EQ(run({"mesh", in, "--out", out, "--iso-percentile", "101"}), 2);
  EXPECT_EQ(run({"mesh", in, "--out", out, "--iso-percentile", "50", "--iso", "1"}), 2);
}

}  // namespace
}  // namespace vox::cli
