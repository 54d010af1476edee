// Boost.Asio, included through one place: Boost 1.74's awaitable.hpp uses std::exchange
// without including <utility>, which GCC 12 no longer pulls in indirectly.
#pragma once

// <utility> must come first (see above).
// clang-format off
#include <utility>
#include <boost/asio.hpp>
// clang-format on
