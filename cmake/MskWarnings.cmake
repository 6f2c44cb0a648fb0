# msk_set_warnings(target): the project's warning set, applied to our own targets only.
function(msk_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
endfunction()
