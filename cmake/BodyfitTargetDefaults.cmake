# Per-target settings shared by every bodyfit target (no directory-wide flags).
function(bodyfit_target_defaults target)
	target_compile_features(${target} PUBLIC cxx_std_17)
	set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
	target_compile_options(${target} PRIVATE -Wall -Wextra)
	if(BODYFIT_SANITIZE)
		target_compile_options(${target} PUBLIC -fsanitize=address,undefined -fno-omit-frame-pointer
			-fno-sanitize-recover=undefined)
		target_link_options(${target} PUBLIC -fsanitize=address,undefined)
	endif()
endfunction()
