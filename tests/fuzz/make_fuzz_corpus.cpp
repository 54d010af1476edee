// Writes the fuzz targets' seed corpus: a few small valid inputs per target (and a few
// refused ones), deterministic, so that the checked-in files can be regenerated after a
// format change:  build-fuzz/bin/make_fuzz_corpus tests/fuzz/corpus
#include <google/protobuf/unknown_field_set.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "proto/framing.hpp"
#include "proto/zstd_codec.hpp"
#include "tests/fuzz/fuzz_meshes.hpp"
#include "voxel.pb.h"

namespace {

using namespace vox;
using Bytes = std::vector<uint8_t>;

// Writes DIR/<target>/<name>; any failure ends the program.
class CorpusDir {
 public:
  explicit CorpusDir(std::filesystem::path root) : root_(std::move(root)) {}
  void write(const std::string& target, const std::string& name, const Bytes& bytes) const {
    const auto dir = root_ / target;
    std::filesystem::create_directories(dir);
    std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    if (!out) {
      std::cerr << "make_fuzz_corpus: cannot write " << (dir / name) << "\n";
      std::exit(1);
    }
  }

 private:
  std::filesystem::path root_;
};

Bytes prefixed(std::initializer_list<uint8_t> head, const Bytes& rest) {
  Bytes out(head);
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

Bytes text(std::string_view s) { return Bytes(s.begin(), s.end()); }
// A string literal with its embedded NUL bytes (not its terminating one).
template <size_t N>
Bytes literal(const char (&s)[N]) {
  return Bytes(s, s + N - 1);
}

Bytes serialized(const wire::Envelope& e) {
  Bytes out(e.ByteSizeLong());
  e.SerializeToArray(out.data(), static_cast<int>(out.size()));
  return out;
}

void set(wire::Vec3* v, float x, float y, float z) {
  v->set_x(x);
  v->set_y(y);
  v->set_z(z);
}

void mesh_corpus(const CorpusDir& out) {
  const std::string t = "mesh_decode_fuzzer";
  proto::ZstdCodec zstd;
  const Bytes base = fuzz::sphere_encoding(fuzz::kBaseRadius, fuzz::kBaseMaterial);
  const Bytes grown = fuzz::sphere_encoding(fuzz::kBaseRadius + 0.4f, fuzz::kBaseMaterial);
  const Bytes other = fuzz::sphere_encoding(2.2f, 7);
  const Bytes empty = fuzz::sphere_encoding(-1.0f, 1);
  out.write(t, "raw_sphere", prefixed({0}, base));
  out.write(t, "raw_empty", prefixed({0}, empty));
  out.write(t, "raw_crc_fixed", prefixed({3}, other));
  // Changes to the level-of-detail seed: a seam face bit, a byte in the rows, one far in.
  out.write(t, "lod_changes", Bytes{4, 16, 0, 2, 60, 0, 1, 0, 8, 4});
  Bytes frame;
  zstd.compress(other, {}, frame);
  out.write(t, "full_frame", prefixed({1}, frame));
  zstd.compress(grown, base, frame);
  out.write(t, "delta_frame", prefixed({2}, frame));
}

std::vector<Bytes> client_messages() {
  std::vector<Bytes> out;
  wire::Envelope e;
  auto* hello = e.mutable_hello();
  hello->set_protocol_version(1);
  hello->set_player_name("fuzz");
  out.push_back(serialized(e));
  e.Clear();
  auto* view = e.mutable_set_view();
  set(view->mutable_position(), 10.5f, 20, -30);
  view->set_radius(4);
  view->set_view_id(1);
  out.push_back(serialized(e));
  e.Clear();
  auto* brush = e.mutable_edit()->mutable_brush();
  e.mutable_edit()->set_request_id(7);
  set(brush->mutable_center(), 1, 2, 3);
  brush->set_radius(3);
  brush->set_strength(0.5f);
  brush->set_material(2);
  out.push_back(serialized(e));
  return out;
}

void envelope_corpus(const CorpusDir& out) {
  const std::string t = "envelope_fuzzer";
  const std::vector<Bytes> basic = client_messages();
  out.write(t, "hello", basic[0]);
  out.write(t, "set_view", basic[1]);
  out.write(t, "edit_brush", basic[2]);
  wire::Envelope e;
  auto edit = [&e](uint64_t id) {
    e.Clear();
    e.mutable_edit()->set_request_id(id);
    return e.mutable_edit();
  };
  auto* x = edit(8)->mutable_explosion();
  set(x->mutable_center(), -40, 5, 17.25f);
  x->set_radius(6);
  x->set_power(1);
  out.write(t, "edit_explosion", serialized(e));
  auto* s = edit(9)->mutable_smooth();
  set(s->mutable_center(), 0, 0, 0);
  s->set_radius(4);
  s->set_strength(0.3f);
  out.write(t, "edit_smooth", serialized(e));
  auto* p = edit(10)->mutable_paint();
  set(p->mutable_center(), 3, -2, 1);
  p->set_radius(2.5f);
  p->set_material(4);
  out.write(t, "edit_paint", serialized(e));
  auto* box = edit(11)->mutable_stamp();
  box->set_shape(wire::Stamp::BOX);
  set(box->mutable_min(), 0.5f, 0.5f, 0.5f);  // the largest edit, off the integer grid
  set(box->mutable_max(), 64.5f, 64.5f, 64.5f);
  box->set_solid(true);
  box->set_material(3);
  out.write(t, "edit_stamp_box", serialized(e));
  auto* ball = edit(12)->mutable_stamp();
  ball->set_shape(wire::Stamp::SPHERE);
  set(ball->mutable_center(), 100, 30, -100);
  ball->set_radius(5);
  out.write(t, "edit_stamp_sphere_air", serialized(e));
  auto* far = edit(13)->mutable_brush();
  set(far->mutable_center(), 1e7f, 0, 0);
  far->set_radius(2);
  far->set_strength(1);
  out.write(t, "edit_out_of_bounds", serialized(e));
  edit(14);
  out.write(t, "edit_without_kind", serialized(e));
  e.Clear();
  auto* r = e.mutable_resync();
  for (int i = 0; i < 3; ++i) {
    auto* c = r->add_coords();
    c->set_x(i);
    c->set_y(-i);
    c->set_z(2 * i);
  }
  out.write(t, "resync", serialized(e));
  e.Clear();
  auto* add = e.mutable_region_command();
  add->set_request_id(20);
  auto* region = add->mutable_add();
  region->set_name("spawn");
  auto* b = region->mutable_box();
  b->set_min_x(-16), b->set_min_y(0), b->set_min_z(-16);
  b->set_max_x(16), b->set_max_y(64), b->set_max_z(16);
  region->set_protect_build(true);
  region->set_protect_explode(true);
  region->add_owners("alice");
  out.write(t, "region_add", serialized(e));
  e.Clear();
  e.mutable_region_command()->set_request_id(21);
  e.mutable_region_command()->mutable_list()->set_after_id(3);
  out.write(t, "region_list", serialized(e));
  e.Clear();
  e.mutable_region_command()->set_request_id(22);
  e.mutable_region_command()->set_remove(7);
  out.write(t, "region_remove", serialized(e));
  e.Clear();
  e.mutable_ping()->set_nonce(99);
  out.write(t, "ping", serialized(e));
  e.Clear();
  e.mutable_welcome()->set_protocol_version(1);
  out.write(t, "server_message", serialized(e));
  auto* unknown = edit(15)->mutable_paint();
  unknown->set_radius(1);
  unknown->set_material(1);
  unknown->GetReflection()->MutableUnknownFields(unknown)->AddVarint(100, 1);
  out.write(t, "edit_unknown_field", serialized(e));
}

void frame_corpus(const CorpusDir& out) {
  const std::string t = "frame_decoder_fuzzer";
  Bytes stream;
  for (const Bytes& m : client_messages()) proto::append_frame(m, stream);
  out.write(t, "three_frames_whole", prefixed({0}, stream));
  out.write(t, "three_frames_split", prefixed({4, 1, 3, 0, 30}, stream));
  Bytes small;
  proto::append_frame(Bytes{}, small);
  proto::append_frame(Bytes(7, 0x41), small);
  small.insert(small.end(), {0xff, 0x01, 0x00, 0x00});  // a 511-byte frame: over the limit
  small.insert(small.end(), 10, 0x42);
  out.write(t, "over_the_limit", prefixed({2, 2, 5}, small));
  Bytes partial;
  proto::append_frame(Bytes(50, 0x43), partial);
  partial.resize(30);
  out.write(t, "partial_frame", prefixed({1, 4}, partial));
}

void volume_corpus(const CorpusDir& out) {
  const std::string t = "volume_file_fuzzer";
  out.write(t, "text_2x2x2", prefixed({0}, text("2 2 2\n-1 -1 -1 -1\n1 1 1 1\n")));
  out.write(t, "text_file_3x2x2",
            prefixed({1}, text("3 2 2\n0.5 -0.25 1e-3 +2 -7 3\n1 1 1 1 1 1\n")));
  out.write(t, "text_header_too_big", prefixed({0}, text("100000 100000 100000\n1 2 3\n")));
  Bytes raw;
  for (int i = 0; i < 12; ++i) {
    const float v = static_cast<float>(i % 3) - 1.0f;
    uint8_t b[4];
    std::memcpy(b, &v, 4);  // little-endian machines only, as the format
    raw.insert(raw.end(), b, b + 4);
  }
  out.write(t, "raw_dims_bytes", prefixed({2, 2, 3, 2}, raw));
  out.write(t, "raw_dims_int32", prefixed({3, 3, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0}, raw));
  out.write(t, "raw_dims_huge", prefixed({3, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0, 0}, raw));
  out.write(t, "dims", prefixed({4}, text("64,32,2")));
  // NIfTI-1: a 2x2x3 int16 volume after the 348-byte header and 4 extension bytes.
  Bytes nii(352, 0);
  auto put16 = [&nii](size_t at, int16_t v) { std::memcpy(nii.data() + at, &v, 2); };
  auto put32 = [&nii](size_t at, auto v) { std::memcpy(nii.data() + at, &v, 4); };
  put32(0, int32_t{348});
  for (int i = 0; i < 8; ++i) put16(40 + 2 * i, i == 0 ? 3 : i == 3 ? 3 : 2);
  put16(70, 4);   // int16
  put16(72, 16);  // bitpix
  for (int a = 1; a <= 3; ++a) put32(76 + 4 * a, 0.5f);
  put32(108, 352.0f);  // vox_offset
  put32(112, 2.0f);    // scl_slope
  std::memcpy(nii.data() + 344, "n+1", 4);
  for (int16_t i = 0; i < 12; ++i) {
    const int16_t v = static_cast<int16_t>(i % 3 - 1);
    nii.insert(nii.end(), reinterpret_cast<const uint8_t*>(&v),
               reinterpret_cast<const uint8_t*>(&v) + 2);
  }
  out.write(t, "nifti_int16", prefixed({5}, nii));
  Bytes nii_huge = nii;  // dims of 30000^3: refused before allocating
  for (int i = 1; i <= 3; ++i) std::memcpy(nii_huge.data() + 40 + 2 * i, "\x30\x75", 2);
  out.write(t, "nifti_huge_dims", prefixed({5}, nii_huge));
  out.write(
      t, "nrrd_raw_uchar",
      prefixed({6}, literal("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                            "spacings: 1 1 2\nencoding: raw\n\n\x00\x01\x00\x01\x02\x02\x00\x00")));
  out.write(t, "nrrd_ascii_short",
            prefixed({6}, text("NRRD0005\n# ascii\ntype: short\ndimension: 3\nsizes: 2 2 2\n"
                               "space directions: (1,0,0) (0,2,0) (0,0,3)\nencoding: ascii\n\n"
                               "-1 0 1 2\n3 -4 5 6\n")));
  out.write(t, "nrrd_gzip_declared_huge",
            prefixed({6}, literal("NRRD0004\ntype: float\ndimension: 3\nsizes: 1000 1000 1000\n"
                                  "encoding: gzip\nendian: little\n\n\x1f\x8b\x08\x00")));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: make_fuzz_corpus DIR   (writes DIR/<target>/<seed>)\n";
    return 2;
  }
  const CorpusDir dir(argv[1]);
  mesh_corpus(dir);
  envelope_corpus(dir);
  frame_corpus(dir);
  volume_corpus(dir);
  return 0;
}
