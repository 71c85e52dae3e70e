# Warning set for every Phalanx target; PHALANX_WERROR turns them into errors (CI does).
function(phalanx_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion
                                           -Wdouble-promotion -Wnon-virtual-dtor -Wold-style-cast)
  if(PHALANX_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# Freestanding rules for code that also runs on the microcontroller (common/, firmware/).
function(phalanx_freestanding target)
  target_compile_options(${target} PRIVATE $<$<COMPILE_LANGUAGE:CXX>:-fno-exceptions -fno-rtti -fno-threadsafe-statics>)
endfunction()
