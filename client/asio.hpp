// Boost.Asio for the client library and its users, included through one place: Boost
// 1.74's awaitable.hpp uses std::exchange without including <utility>, which GCC 12 no
// longer pulls in indirectly. (The server has its own, server/net/asio.hpp: the client
// includes nothing from server/.)
#pragma once

// <utility> must come first (see above).
// clang-format off
#include <utility>
#include <boost/asio.hpp>
// clang-format on
