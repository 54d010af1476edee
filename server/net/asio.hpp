// Boost.Asio, included through one place: Boost 1.74's awaitable.hpp uses std::exchange
// without including <utility>, which GCC 12 no longer pulls in indirectly.
#pragma once

// <utility> must come first (see above).
// clang-format off
#include <utility>
#include <boost/asio.hpp>
// clang-format on

#include <chrono>

namespace vox::net {

// The executor a connection, its session and their timers run on: a strand of the
// io_context, named by its concrete type. A type-erased any_io_executor holding a strand
// does not fit in its small-object buffer, so every copy of it — several per asynchronous
// operation — was a heap allocation.
using Strand = boost::asio::strand<boost::asio::io_context::executor_type>;
using StrandSocket = boost::asio::basic_stream_socket<boost::asio::ip::tcp, Strand>;
using StrandTimer =
    boost::asio::basic_waitable_timer<std::chrono::steady_clock,
                                      boost::asio::wait_traits<std::chrono::steady_clock>, Strand>;

}  // namespace vox::net
