# Warning and sanitizer flags shared by every OPL target.
add_library(opl_warnings INTERFACE)
target_compile_options(opl_warnings INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wshadow=local -Wnon-virtual-dtor>)

if(OPL_SANITIZE)
  string(REPLACE "," ";" _opl_san_list "${OPL_SANITIZE}")
  foreach(_s IN LISTS _opl_san_list)
    add_compile_options(-fsanitize=${_s})
    add_link_options(-fsanitize=${_s})
  endforeach()
  add_compile_options(-fno-omit-frame-pointer -fno-sanitize-recover=all)
  # Eigen drops its "glibc malloc is 16-byte aligned" assumption when
  # __SANITIZE_ADDRESS__ is defined and then frees with its own aligned free,
  # which does not match Debian's libceres (built without sanitizers): Eigen
  # objects allocated inside libceres (e.g. GradientChecker::ProbeResults) would
  # be freed wrongly. Keep the allocator ABI of the system libraries.
  add_compile_definitions(EIGEN_MALLOC_ALREADY_ALIGNED=1)
  add_link_options(-fno-sanitize-recover=all)
endif()
