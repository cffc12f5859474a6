# Precompiled headers (build time, issue 38: CI's clean build took 35 of its 60 minutes).
#
# GCC uses a precompiled header only in a translation unit compiled with the same code
# generation flags (-fPIC for the libraries, -fPIE for the executables) and the same macros that
# the header's text looks at (CGAL_LINKED_WITH_TBB, NOMINMAX, BOOST_ALL_NO_LIB, ...); otherwise it
# parses the header's text instead (slower than without it). So there are three hosts, one per
# kind of translation unit, each linking what its kind links, and every target names its kind:
#   rgbd_use_pch(<target> LIBRARY)     static libraries above rgbd_toolkit (they link CGAL)
#   rgbd_use_pch(<target> ALGORITHMS)  rgbd_algorithms (CGAL's TBB support on)
#   rgbd_use_pch(<target> EXECUTABLE)  tools and tests that link an rgbd:: library
# -Winvalid-pch names a translation unit that cannot use its kind's header. RGBD_PCH=OFF turns
# it all off (a compiler other than GCC, or a check that every file includes what it uses).
option(RGBD_PCH "Precompile the third-party headers most translation units include" ON)

set(RGBD_PCH_DIR ${CMAKE_CURRENT_LIST_DIR})
if(RGBD_PCH AND NOT CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  set(RGBD_PCH OFF)
endif()

if(RGBD_PCH)
  set(_rgbd_pch_libs CGAL::CGAL Eigen3::Eigen nlohmann_json::nlohmann_json opencv_core)
  add_library(rgbd_pch_library OBJECT ${RGBD_PCH_DIR}/host.cpp)
  target_link_libraries(rgbd_pch_library PRIVATE ${_rgbd_pch_libs})
  add_library(rgbd_pch_algorithms OBJECT ${RGBD_PCH_DIR}/host.cpp)
  target_link_libraries(rgbd_pch_algorithms PRIVATE ${_rgbd_pch_libs} CGAL::TBB_support)
  add_executable(rgbd_pch_executable ${RGBD_PCH_DIR}/host_main.cpp)
  target_link_libraries(rgbd_pch_executable PRIVATE ${_rgbd_pch_libs})
  foreach(host library algorithms executable)
    target_precompile_headers(rgbd_pch_${host} PRIVATE ${RGBD_PCH_DIR}/precompiled.hpp)
    target_compile_options(rgbd_pch_${host} PRIVATE -Winvalid-pch)
  endforeach()
endif()

# rgbd_use_pch(<target> LIBRARY|ALGORITHMS|EXECUTABLE): <target> reuses that kind's header.
function(rgbd_use_pch target kind)
  if(NOT RGBD_PCH)
    return()
  endif()
  string(TOLOWER ${kind} host)
  target_precompile_headers(${target} REUSE_FROM rgbd_pch_${host})
  target_compile_options(${target} PRIVATE -Winvalid-pch)
endfunction()
