// How the PostgreSQL code turns libpqxx's failures into StoreError: one line naming the
// store, after `drop` forgets the connection (the next call reconnects). Only for the
// store's .cpp files (it includes libpqxx).
#pragma once

#include <pqxx/pqxx>
#include <string>

#include "server/store/postgres_store.hpp"

namespace vox::store {

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

}  // namespace vox::store
