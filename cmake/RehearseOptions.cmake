# Warnings applied to the project's own targets (not to third-party headers).
add_library(rehearse_warnings INTERFACE)
target_compile_options(rehearse_warnings INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wno-unused-parameter $<$<CXX_COMPILER_ID:GNU>:-Wno-restrict>>)
