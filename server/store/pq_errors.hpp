// How the PostgreSQL code turns libpqxx's failures into StoreError: one line naming the
// store, after `drop` forgets the connection (the next call reconnects). Only for the
// store's .cpp files (it includes libpqxx).
#pragma once

#include <algorithm>
#include <chrono>
#include <memory>
#include <pqxx/pqxx>
#include <string>

#include "server/store/postgres_store.hpp"

namespace vox::store {

// The connection string with a connect timeout, unless it sets one: a database host gone
// silent must not hold a caller (the pipeline thread reads chunks and regions; the ban
// keeper's stop waits for its thread) for the system's TCP timeout.
inline std::string with_connect_timeout(const std::string& uri, std::chrono::milliseconds wait) {
  if (uri.find("connect_timeout") != std::string::npos) return uri;
  const bool url = uri.rfind("postgres://", 0) == 0 || uri.rfind("postgresql://", 0) == 0;
  std::string out = uri;
  out += !url ? " " : uri.find('?') == std::string::npos ? "?" : "&";  // else key=value pairs
  out += "connect_timeout=";
  out += std::to_string(std::max<int64_t>(2, wait.count() / 1000));
  return out;
}

template <typename Fn, typename Drop>
auto translate_pq_errors(const std::string& name, Drop&& drop, Fn&& fn) {
  try {
    return fn();
  } catch (const StoreError&) {
    throw;
  } catch (const pqxx::broken_connection& e) {
    drop();
    throw StoreError(name + ": connection lost: " + first_line(e.what()));
  } catch (const std::exception& e) {
    drop();
    throw StoreError(name + ": " + first_line(e.what()));
  }
}

// Runs fn on `conn`: opened by `open` (which does what a new connection needs) when there
// is none or it broke; every libpqxx failure a StoreError naming `name`, the connection
// dropped (the next call reopens it).
template <typename Open, typename Fn>
void run_on(std::unique_ptr<pqxx::connection>& conn, const std::string& name, Open&& open,
            Fn&& fn) {
  translate_pq_errors(
      name, [&] { conn.reset(); },
      [&] {
        if (!conn || !conn->is_open()) conn = open();
        fn(*conn);
      });
}

}  // namespace vox::store
