# Warnings applied to the project's own targets (not to third-party headers).
add_library(rehearse_warnings INTERFACE)
target_compile_options(rehearse_warnings INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wno-unused-parameter $<$<CXX_COMPILER_ID:GNU>:-Wno-restrict>>)

# Recorded rehearsals verify bit for bit on any x86-64 processor (issue 60): what a recording's checksums cover must not
# depend on the machine that built or runs it. Flags that let the compiler pick instructions by machine (-march=native,
# AVX or FMA: Eigen's packets change width, so its sums change order; contracted multiply-adds round once instead of
# twice) or reorder floating point (-ffast-math) are refused, and multiply-adds are never contracted.
foreach(flags_var CMAKE_CXX_FLAGS CMAKE_C_FLAGS CMAKE_CXX_FLAGS_RELEASE CMAKE_CXX_FLAGS_RELWITHDEBINFO)
  if("${${flags_var}}" MATCHES "(^| )(-march=[^ ]*|-mavx[^ ]*|-mfma[^ ]*|-ffast-math|-Ofast|-ffp-contract=fast)( |$)")
    message(FATAL_ERROR "${flags_var} holds '${CMAKE_MATCH_2}': a recorded rehearsal would then replay differently on "
                        "another processor; build for the x86-64 baseline (remove it)")
  endif()
endforeach()
add_compile_options($<$<COMPILE_LANG_AND_ID:CXX,GNU,Clang>:-ffp-contract=off>)
