//! The compensation network (input layer -> LSTM -> output layer, one streaming step
//! per control tick), in one vocabulary:
//!
//! | module | what |
//! |---|---|
//! | [`format`] | the formats every other part names: Q formats and cell-update constants, weight formats ([`format::I16Weights`], [`format::I8Weights`]), a compiled-in network's integer format ([`format::QuantFormat`]), the integer recurrent state ([`format::QuantState`]), [`format::InputActivation`], [`format::Precision`], [`format::FeaturePreset`]; uses no kernel, so `dsp` builds on it |
//! | [`reference`](mod@reference) | [`reference::Lstm`]: the f32 reference step in PyTorch's layout (the host's training and evaluation run its shape-erased [`reference::LstmView`]) |
//! | [`kernels`] | the compiled-in networks for the Cortex-M4: [`kernels::F32Lstm`] (f32, blocked layout) and [`kernels::QuantLstm`] (int16 or int8 weights, int16 activations), their shape-erased views run by the exporter |
//! | [`act`] | the integer kernels' sigmoid and tanh by direct table lookup (tables written by `build.rs`) |

pub mod act;
pub mod format;
pub mod kernels;
pub mod reference;
