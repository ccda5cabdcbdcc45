# How every rangex target is built, in one place.
#
# rangex_layer(TARGET LAYER): the target belongs to server/LAYER. Its public include root is a
# folder of the build tree holding a link to server/LAYER alone, so that a file sees the
# headers of its own layer and of the layers its target links, and no other: a pipeline file
# that includes "service/engine.h" does not compile. Its warnings and the architecture are
# set with it.
#
# rangex_flags(TARGET [PORTABLE]): the warnings, and -march=native (RANGEX_NATIVE) unless
# PORTABLE. rangex_calib is portable: Debian's Ceres is built for baseline x86-64, and the
# Eigen templates instantiated in calib must agree with it on alignment and vector width
# (the one definition rule).
option(RANGEX_NATIVE "Optimise for the build machine's CPU (-march=native)" ON)

# The server is built on the machine it runs on (or one like it): the compiler may use its
# vector units. Off: a portable binary.
set(RANGEX_ARCH_FLAGS "")
if(RANGEX_NATIVE)
  set(RANGEX_ARCH_FLAGS -march=native)
endif()
add_library(rangex_native_arch INTERFACE)
target_compile_options(rangex_native_arch INTERFACE ${RANGEX_ARCH_FLAGS})

function(rangex_flags target)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  if(NOT "PORTABLE" IN_LIST ARGN)
    target_link_libraries(${target} PRIVATE rangex_native_arch)
  endif()
endfunction()

function(rangex_layer target layer)
  set(root ${PROJECT_BINARY_DIR}/layers/${layer})
  if(NOT EXISTS ${root}/${layer})
    file(MAKE_DIRECTORY ${root})
    file(CREATE_LINK ${PROJECT_SOURCE_DIR}/server/${layer} ${root}/${layer} SYMBOLIC)
  endif()
  target_include_directories(${target} PUBLIC ${root})
  rangex_flags(${target} ${ARGN})
endfunction()
