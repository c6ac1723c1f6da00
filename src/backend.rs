//! Run-time choice of the burn backend. burn 0.22 picks the backend through the `Device`, so
//! swapping NdArray, Flex and Wgpu is a flag, not a recompile of model or simulator code; a
//! backend whose cargo feature was not enabled is a clear error. The default build has Flex
//! and NdArray; `--no-default-features` leaves NdArray alone (what the test suite builds).

use burn::prelude::*;

use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// burn-ndarray on the CPU (always built).
    NdArray,
    /// burn's newer pure-Rust CPU backend (cargo feature `flex`).
    Flex,
    /// GPU through wgpu (cargo feature `wgpu`; software Vulkan where there is no GPU).
    Wgpu,
}

impl std::str::FromStr for Backend {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "ndarray" => Ok(Backend::NdArray),
            "flex" => Ok(Backend::Flex),
            "wgpu" => Ok(Backend::Wgpu),
            other => Err(Error::InvalidArgument(format!(
                "unknown backend `{other}`: expected ndarray, flex or wgpu"
            ))),
        }
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Backend::NdArray => "ndarray",
            Backend::Flex => "flex",
            Backend::Wgpu => "wgpu",
        })
    }
}

impl Backend {
    /// The CPU backend training and evaluation use unless told otherwise: Flex where it is
    /// built in (the default features), else NdArray. Flex was 1.4-2x faster on the paper-size
    /// network's forward + backward and the training steps, measured side by side
    /// (docs/backends-and-speed.md, "Training speed").
    pub fn cpu_default() -> Self {
        if cfg!(feature = "flex") {
            Backend::Flex
        } else {
            Backend::NdArray
        }
    }

    /// Whether this build has the backend (its cargo feature was enabled).
    pub fn is_compiled(self) -> bool {
        match self {
            Backend::NdArray => true,
            Backend::Flex => cfg!(feature = "flex"),
            Backend::Wgpu => cfg!(feature = "wgpu"),
        }
    }

    /// The device, with autodiff when `autodiff` (training, gradient checks).
    pub fn device(self, autodiff: bool) -> Result<Device> {
        let device = self.plain_device()?;
        Ok(if autodiff { device.autodiff() } else { device })
    }

    /// The CPU device every build has (NdArray), plain or with autodiff: the tests' reference
    /// device, and where host-side code needs a device but no backend choice.
    pub fn reference_device(autodiff: bool) -> Device {
        #[allow(deprecated)] // burn deprecates NdArray in favour of Flex; both are kept
        let device = Device::ndarray();
        if autodiff { device.autodiff() } else { device }
    }

    fn plain_device(self) -> Result<Device> {
        match self {
            Backend::NdArray => Ok(Self::reference_device(false)),
            #[cfg(feature = "flex")]
            Backend::Flex => Ok(Device::flex()),
            #[cfg(feature = "wgpu")]
            Backend::Wgpu => Ok(Device::wgpu(Default::default())),
            #[allow(unreachable_patterns)]
            other => Err(Error::InvalidArgument(format!(
                "rtr was built without the `{other}` backend: rebuild with `--features {other}`"
            ))),
        }
    }
}
