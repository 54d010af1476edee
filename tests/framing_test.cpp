#include "proto/framing.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "tests/alloc_counter.hpp"

namespace vox::proto {
namespace {

TEST(FrameDecoder, ReassemblesFramesSplitAnywhere) {
  std::vector<uint8_t> stream;
  const std::vector<uint8_t> a = {1, 2, 3}, b = {}, c(1000, 7);
  append_frame(a, stream);
  append_frame(b, stream);
  append_frame(c, stream);
  for (size_t step = 1; step <= stream.size(); step = step * 2 + 1) {
    FrameDecoder d(4096);
    std::vector<std::vector<uint8_t>> got;
    for (size_t i = 0; i < stream.size(); i += step) {
      d.feed(std::span(stream).subspan(i, std::min(step, stream.size() - i)));
      while (auto f = d.next()) got.push_back(*f);
    }
    ASSERT_EQ(got.size(), 3u) << "step " << step;
    EXPECT_EQ(got[0], a);
    EXPECT_EQ(got[1], b);
    EXPECT_EQ(got[2], c);
  }
}

TEST(FrameDecoder, RejectsEveryTruncationAsIncomplete) {
  std::vector<uint8_t> frame;
  append_frame(std::vector<uint8_t>(50, 9), frame);
  for (size_t n = 0; n < frame.size(); ++n) {
    FrameDecoder d(4096);
    d.feed(std::span(frame).first(n));
    EXPECT_FALSE(d.next()) << "length " << n;
    EXPECT_TRUE(d.error().empty());
  }
}

// The length is untrusted: a header declaring 1 MiB against a 100-byte limit is refused
// from the header alone. Nothing of the declared size is allocated, only the error message.
TEST(FrameDecoder, RefusesALengthOverTheLimitBeforeAllocating) {
  constexpr uint32_t kDeclared = 1 << 20;
  std::vector<uint8_t> header;
  for (int i = 0; i < 4; ++i) header.push_back(static_cast<uint8_t>(kDeclared >> (8 * i)));
  ASSERT_EQ(read_frame_length(header.data()), kDeclared);
  const std::vector<uint8_t> more_body(4096, 1);
  FrameDecoder d(100);
  const size_t bytes_before = test::bytes_allocated_on_this_thread();
  d.feed(header);
  EXPECT_FALSE(d.next());
  const size_t bytes = test::bytes_allocated_on_this_thread() - bytes_before;
  EXPECT_LT(bytes, 1024u) << "allocated for the declared length";
  EXPECT_NE(d.error().find("over the limit"), std::string::npos) << d.error();
  // It stays failed: what follows is neither buffered nor allocated for.
  const size_t allocations_before = test::allocations_on_this_thread();
  d.feed(more_body);
  d.feed(header);
  EXPECT_FALSE(d.next());
  EXPECT_EQ(test::allocations_on_this_thread() - allocations_before, 0u);
  EXPECT_EQ(d.buffered(), 0u);
}

}  // namespace
}  // namespace vox::proto
