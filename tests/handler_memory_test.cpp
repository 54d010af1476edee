// The memory a connection's asynchronous operations are allocated from.
#include "server/net/handler_memory.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>

namespace vox::net {
namespace {

namespace asio = boost::asio;
using namespace std::chrono_literals;

// Found by TSan in WsConnection.WritingMessagesOnceWarmAllocatesNothing: the connection was
// destroyed with its write deadline pending. The cancelled timer's handler was moved out of
// its operation, the operation's block given back (the last reference: the memory freed),
// and the handler then posted to its strand: a new operation allocated from freed memory.
TEST(HandlerMemory, ATimersHandlerOutlivingItsConnectionStillHasItsMemory) {
  asio::io_context io;
  Strand strand(io.get_executor());
  HandlerMemory::Owner memory = HandlerMemory::make();
  auto timer = std::make_unique<StrandTimer>(strand);
  timer->expires_after(1h);
  int ran = 0;
  bool aborted = false;
  timer->async_wait(with_memory(memory, [&](boost::system::error_code ec) {
    ++ran;
    aborted = ec == asio::error::operation_aborted;
  }));
  memory.reset();  // the connection goes, its timer with it
  timer.reset();
  io.run_for(1s);
  EXPECT_EQ(ran, 1);
  EXPECT_TRUE(aborted);
}

// A handler copied and destroyed in any order keeps the memory until the last copy goes.
TEST(HandlerMemory, EachHandlerCopyHoldsTheMemory) {
  HandlerMemory::Owner memory = HandlerMemory::make();
  auto handler = with_memory(memory, [] {});
  auto copy = handler;
  memory.reset();
  {
    auto moved = std::move(handler);
    HandlerAllocator<unsigned char> alloc(moved.get_allocator());
    unsigned char* p = alloc.allocate(100);  // from a block of memory still alive
    alloc.deallocate(p, 100);
  }
  HandlerAllocator<unsigned char> alloc(copy.get_allocator());
  unsigned char* p = alloc.allocate(HandlerMemory::kBlockBytes);
  alloc.deallocate(p, HandlerMemory::kBlockBytes);
}

}  // namespace
}  // namespace vox::net
