// libFuzzer target for the stream framing (proto/framing.hpp): arbitrary bytes fed to a
// FrameDecoder in arbitrary pieces, drained after every piece as a session does.
// Input: byte 0 gives the number of pieces before the last (0..15), the next bytes their
// lengths (0..255 each, cut at the end of the stream), then the stream itself.
// Checked against a plain reading of the same stream: the same frames whatever the
// split, an error exactly when a length over the limit is reached, no frame over the
// limit, and never more than one incomplete frame held.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <span>
#include <vector>

#include "proto/framing.hpp"

namespace {

constexpr size_t kMaxFrameBytes = 200;  // small, so the fuzzer reaches it easily
constexpr size_t kMaxPieces = 16;

struct Reading {
  std::vector<std::vector<uint8_t>> frames;
  bool over_limit = false;
};

// What the stream holds: frames up to the first length over the limit.
Reading read_plainly(std::span<const uint8_t> stream) {
  Reading r;
  size_t at = 0;
  while (stream.size() - at >= vox::proto::kFrameHeaderBytes) {
    const uint32_t n = vox::proto::read_frame_length(stream.data() + at);
    if (n > kMaxFrameBytes) {
      r.over_limit = true;
      break;
    }
    if (stream.size() - at - vox::proto::kFrameHeaderBytes < n) break;
    const auto body = stream.subspan(at + vox::proto::kFrameHeaderBytes, n);
    r.frames.emplace_back(body.begin(), body.end());
    at += vox::proto::kFrameHeaderBytes + n;
  }
  return r;
}

void check(bool ok) {
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const size_t pieces = std::min<size_t>(data[0] % kMaxPieces, size - 1);
  const std::span<const uint8_t> lengths(data + 1, pieces);
  const std::span<const uint8_t> stream(data + 1 + pieces, size - 1 - pieces);

  vox::proto::FrameDecoder decoder(kMaxFrameBytes);
  std::vector<std::vector<uint8_t>> frames;
  size_t fed = 0;
  auto feed = [&](size_t n) {
    decoder.feed(stream.subspan(fed, n));
    fed += n;
    while (auto frame = decoder.next()) {
      check(frame->size() <= kMaxFrameBytes);
      frames.push_back(std::move(*frame));
    }
    if (!decoder.error().empty()) {
      check(decoder.buffered() == 0);
    } else {
      check(decoder.buffered() < vox::proto::kFrameHeaderBytes + kMaxFrameBytes);
    }
  };
  for (uint8_t length : lengths) feed(std::min<size_t>(length, stream.size() - fed));
  feed(stream.size() - fed);

  const Reading expected = read_plainly(stream);
  check(frames == expected.frames);
  check(decoder.error().empty() != expected.over_limit);
  // After an error the decoder takes nothing more.
  if (expected.over_limit) {
    decoder.feed(stream);
    check(!decoder.next() && decoder.buffered() == 0);
  }
  return 0;
}
