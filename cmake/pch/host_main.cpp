// The translation unit that the executables' precompiled header is built for
// (PrecompiledHeaders.cmake): an executable, so that it is compiled as executables are (-fPIE).
int main() { return 0; }
