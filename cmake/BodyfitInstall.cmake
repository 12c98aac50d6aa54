# Installation and the CMake package (find_package(bodyfit)) are set up with the Bullet extension.
