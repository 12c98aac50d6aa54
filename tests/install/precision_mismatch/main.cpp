// Compiled with the other Bullet precision than the installed package (see CMakeLists.txt): must not compile.
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

int main() { return 0; }
