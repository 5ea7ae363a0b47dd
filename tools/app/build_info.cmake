# build_info.cmake - run at every build (cmake -P, from tools/app/CMakeLists.txt): writes OUT,
# the source of build_info.cpp's values, with the git commit of the tree at SRC and whether
# its tracked files differ from it. OUT is rewritten only when its text changes, so an
# unchanged tree recompiles nothing.
execute_process(COMMAND git -C "${SRC}" rev-parse HEAD
                OUTPUT_VARIABLE commit RESULT_VARIABLE rc ERROR_QUIET
                OUTPUT_STRIP_TRAILING_WHITESPACE)
set(dirty "false")
if(NOT rc EQUAL 0 OR commit STREQUAL "")
  set(commit "unknown")  # not a git checkout (a source archive), no git, or git refused it
else()
  # tracked files only: the build folders and run outputs inside the tree are not the source
  execute_process(COMMAND git -C "${SRC}" status --porcelain --untracked-files=no
                  OUTPUT_VARIABLE changes RESULT_VARIABLE rc ERROR_QUIET)
  if(NOT rc EQUAL 0)
    set(dirty "unknown")
  elseif(NOT changes STREQUAL "")
    set(dirty "true")
  endif()
endif()
file(WRITE "${OUT}.new"
     "// written by tools/app/build_info.cmake at build time: do not edit\n"
     "#define ESIM_BUILD_VERSION \"${VERSION}\"\n"
     "#define ESIM_BUILD_COMMIT \"${commit}\"\n"
     "#define ESIM_BUILD_DIRTY \"${dirty}\"\n")
execute_process(COMMAND "${CMAKE_COMMAND}" -E copy_if_different "${OUT}.new" "${OUT}")
file(REMOVE "${OUT}.new")
