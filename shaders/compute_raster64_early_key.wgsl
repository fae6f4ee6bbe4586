// The 64-bit pass's early depth test on the whole key (RasterKernel::early_key, devices with
// ShaderInt64AtomicAllOps): an atomic load of the pixel's 64-bit key through the binding the
// atomicMin writes, so that the two share an address and a range check; a key no smaller than
// the pixel's (ties in depth included) skips the atomic.
alias Early = u64;

fn early_value(pixel: u32) -> u64 {
  return atomicLoad(&visibility[pixel]);
}

fn early_hidden(key: u64, early: u64) -> bool {
  return key >= early;
}
