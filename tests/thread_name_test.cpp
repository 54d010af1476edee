// name_this_thread and named_thread: the name the kernel shows for the thread, cut to 15
// characters.
#include "server/world/thread_name.hpp"

#include <gtest/gtest.h>
#include <pthread.h>

#include <string>
#include <thread>

namespace vox {
namespace {

std::string name_in(const char* name) {
  std::string seen;
  std::thread([&] {
    name_this_thread(name);
    char buf[64] = {};
    pthread_getname_np(pthread_self(), buf, sizeof buf);
    seen = buf;
  }).join();
  return seen;
}

TEST(ThreadName, TheKernelShowsTheNameCutTo15Characters) {
  EXPECT_EQ(name_in("vox-appender"), "vox-appender");
  EXPECT_EQ(name_in("vox-a-name-longer-than-fifteen"), "vox-a-name-long");
}

TEST(ThreadName, ANamedThreadRunsItsBodyUnderItsName) {
  std::string seen;
  named_thread("vox-test", [&] {
    char buf[64] = {};
    pthread_getname_np(pthread_self(), buf, sizeof buf);
    seen = buf;
  }).join();
  EXPECT_EQ(seen, "vox-test");
}

}  // namespace
}  // namespace vox
