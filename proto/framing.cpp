#include "proto/framing.hpp"

#include <google/protobuf/message_lite.h>

namespace vox::proto {

void append_frame(std::span<const uint8_t> body, std::vector<uint8_t>& out) {
  const auto n = static_cast<uint32_t>(body.size());
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(n >> (8 * i)));
  out.insert(out.end(), body.begin(), body.end());
}

uint32_t read_frame_length(const uint8_t* h) {
  return static_cast<uint32_t>(h[0]) | static_cast<uint32_t>(h[1]) << 8 |
         static_cast<uint32_t>(h[2]) << 16 | static_cast<uint32_t>(h[3]) << 24;
}

void FrameDecoder::feed(std::span<const uint8_t> bytes) {
  if (!error_.empty()) return;
  if (start_ > 0 && start_ == buffer_.size()) {
    buffer_.clear();
    start_ = 0;
  }
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

std::optional<std::vector<uint8_t>> FrameDecoder::next() {
  if (!error_.empty() || buffered() < kFrameHeaderBytes) return std::nullopt;
  const uint32_t n = read_frame_length(buffer_.data() + start_);
  if (n > max_) {
    error_ =
        "frame of " + std::to_string(n) + " bytes is over the limit of " + std::to_string(max_);
    buffer_.clear();
    start_ = 0;
    return std::nullopt;
  }
  if (buffered() < kFrameHeaderBytes + n) return std::nullopt;
  const auto* body = buffer_.data() + start_ + kFrameHeaderBytes;
  std::vector<uint8_t> frame(body, body + n);
  start_ += kFrameHeaderBytes + n;
  if (start_ > 65536 && start_ * 2 > buffer_.size()) {  // compact now and then
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<long>(start_));
    start_ = 0;
  }
  return frame;
}

void append_framed(const google::protobuf::MessageLite& message, std::vector<uint8_t>& out) {
  const size_t n = message.ByteSizeLong();
  const size_t at = out.size();
  out.resize(at + kFrameHeaderBytes + n);
  for (size_t i = 0; i < kFrameHeaderBytes; ++i) out[at + i] = static_cast<uint8_t>(n >> (8 * i));
  message.SerializeWithCachedSizesToArray(out.data() + at + kFrameHeaderBytes);
}

}  // namespace vox::proto
