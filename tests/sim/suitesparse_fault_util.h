// suitesparse_fault_util.h - memory that runs out inside CHOLMOD, for the tests of its
// callers: while a FailingSuiteSparseMalloc lives, every allocation SuiteSparse makes fails
// (SuiteSparse_config's allocators, which CHOLMOD calls), as on a machine out of memory.
#pragma once

#include <SuiteSparse_config.h>

#include <cstddef>

namespace esim::test {

class FailingSuiteSparseMalloc {
 public:
  FailingSuiteSparseMalloc() : saved_(SuiteSparse_config) {
    SuiteSparse_config.malloc_func = [](size_t) -> void* { return nullptr; };
    SuiteSparse_config.calloc_func = [](size_t, size_t) -> void* { return nullptr; };
    SuiteSparse_config.realloc_func = [](void*, size_t) -> void* { return nullptr; };
  }
  ~FailingSuiteSparseMalloc() { SuiteSparse_config = saved_; }
  FailingSuiteSparseMalloc(const FailingSuiteSparseMalloc&) = delete;
  FailingSuiteSparseMalloc& operator=(const FailingSuiteSparseMalloc&) = delete;

 private:
  SuiteSparse_config_struct saved_;
};

}  // namespace esim::test
