// Little-endian bytes for the formats voxeld writes itself (the world store's edit
// records, the cluster's messages): a writer that appends, and a reader that never reads
// past its span — a read past the end yields zeros and marks the reader failed, so a
// decoder reads on and checks ok() (or done()) once. Pure; any thread.
#pragma once

#include <bit>
#include <cstdint>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

namespace vox::world {

class ByteWriter {
 public:
  ByteWriter() { out_.reserve(64); }
  // Starts with `head` (a format's version and kind bytes).
  explicit ByteWriter(std::initializer_list<uint8_t> head) {
    out_.reserve(64);
    out_.insert(out_.end(), head.begin(), head.end());
  }
  ByteWriter& u8(uint8_t v) {
    out_.push_back(v);
    return *this;
  }
  ByteWriter& u16(uint16_t v) { return le(v); }
  ByteWriter& u32(uint32_t v) { return le(v); }
  ByteWriter& u64(uint64_t v) { return le(v); }
  ByteWriter& i32(int32_t v) { return le(static_cast<uint32_t>(v)); }
  ByteWriter& f32(float v) { return le(std::bit_cast<uint32_t>(v)); }
  ByteWriter& bytes(std::span<const uint8_t> b) {
    out_.insert(out_.end(), b.begin(), b.end());
    return *this;
  }
  ByteWriter& text(const std::string& s) {  // as it is: the caller writes its length
    out_.insert(out_.end(), s.begin(), s.end());
    return *this;
  }
  std::vector<uint8_t> take() { return std::move(out_); }

 private:
  template <typename T>
  ByteWriter& le(T v) {
    for (size_t i = 0; i < sizeof(T); ++i) out_.push_back(static_cast<uint8_t>(v >> (8 * i)));
    return *this;
  }
  std::vector<uint8_t> out_;
};

class ByteReader {
 public:
  explicit ByteReader(std::span<const uint8_t> in) : in_(in) {}
  uint8_t u8() { return need(1) ? in_[at_++] : 0; }
  uint16_t u16() { return le<uint16_t>(); }
  uint32_t u32() { return le<uint32_t>(); }
  uint64_t u64() { return le<uint64_t>(); }
  int32_t i32() { return static_cast<int32_t>(le<uint32_t>()); }
  float f32() { return std::bit_cast<float>(le<uint32_t>()); }
  // `n` bytes as text (empty, and failed, when fewer are left).
  std::string text(size_t n) {
    if (!need(n)) return {};
    std::string s(reinterpret_cast<const char*>(in_.data() + at_), n);
    at_ += n;
    return s;
  }
  std::span<const uint8_t> rest() {
    const auto r = in_.subspan(at_);
    at_ = in_.size();
    return r;
  }
  void fail() { ok_ = false; }
  bool ok() const { return ok_; }
  bool done() const { return ok_ && at_ == in_.size(); }  // every byte read, none past

 private:
  bool need(size_t n) {
    if (ok_ && in_.size() - at_ >= n) return true;
    ok_ = false;
    return false;
  }
  template <typename T>
  T le() {
    if (!need(sizeof(T))) return 0;
    T v = 0;
    for (size_t i = 0; i < sizeof(T); ++i) v |= static_cast<T>(T{in_[at_ + i]} << (8 * i));
    at_ += sizeof(T);
    return v;
  }
  std::span<const uint8_t> in_;
  size_t at_ = 0;
  bool ok_ = true;
};

}  // namespace vox::world
