# Helpers that register visloc libraries and tests so every module declares what it links.
#
#   visloc_add_library(NAME SRCS a.cc b.cc DEPS visloc::geometry Eigen3::Eigen PRIVATE_DEPS ...)
# creates target visloc_NAME with alias visloc::NAME. Headers are included from the repository
# root ("core/geometry/rigid3.h"), so the include path names the module.
function(visloc_add_library NAME)
  cmake_parse_arguments(ARG "" "" "SRCS;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(visloc_${NAME} STATIC ${ARG_SRCS})
  add_library(visloc::${NAME} ALIAS visloc_${NAME})
  target_include_directories(visloc_${NAME} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(visloc_${NAME} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  target_compile_options(visloc_${NAME} PRIVATE ${VISLOC_WARNINGS})
endfunction()

#   visloc_add_test(NAME SRCS foo_test.cc DEPS visloc::foo)
# builds a GTest executable and registers each test case with CTest.
function(visloc_add_test NAME)
  if(NOT VISLOC_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SRCS;DEPS;PROPERTIES" ${ARGN})
  add_executable(${NAME} ${ARG_SRCS})
  target_link_libraries(${NAME} PRIVATE ${ARG_DEPS} GTest::gmock GTest::gtest GTest::gtest_main)
  target_compile_options(${NAME} PRIVATE ${VISLOC_WARNINGS})
  if(VISLOC_SANITIZE)
    # The tests' own code is compiled without optimization in the sanitizer builds (the code
    # under test keeps -O1): it is not where a test spends its time, and optimizing it under
    # instrumentation cost ~40% more compile time per test file, most of the CI's build.
    target_compile_options(${NAME} PRIVATE -O0)
  endif()
  gtest_discover_tests(${NAME} DISCOVERY_TIMEOUT 60 PROPERTIES ${ARG_PROPERTIES})
endfunction()

#   visloc_hot_loops_under_sanitizers(a.cc b.cc [UNINSTRUMENTED])
# compiles a module's pixel loops at -O2 in the sanitizer builds (the rest stays at -O1): the
# sanitized suite spends most of its time in them, and at -O1 GCC does not vectorize them.
# Still instrumented unless UNINSTRUMENTED (the simulator's renderer, which makes test data
# and is not the product's code path). The bits they compute do not change: -ffp-contract=off
# everywhere and no fast math. Call it from the directory that owns the sources.
function(visloc_hot_loops_under_sanitizers)
  cmake_parse_arguments(ARG "UNINSTRUMENTED" "" "" ${ARGN})
  if(NOT VISLOC_SANITIZE)
    return()
  endif()
  set(options -O2)
  if(ARG_UNINSTRUMENTED)
    list(APPEND options -fno-sanitize=all)
  endif()
  # Appended: a file's own options (descriptor.cc's -fno-math-errno, say) stay.
  set_property(SOURCE ${ARG_UNPARSED_ARGUMENTS} APPEND PROPERTY COMPILE_OPTIONS ${options})
endfunction()
