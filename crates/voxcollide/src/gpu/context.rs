//! `GpuContext`: the device and queue the GPU backend runs on — found here, or the app's own.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use wgpu::{Adapter, AdapterInfo, Backend, DeviceType};

use crate::error::Error;

/// A wgpu device and queue for [`GpuCollision`](crate::GpuCollision).
///
/// Cloning is cheap (the device and queue are shared handles).
#[derive(Clone, Debug)]
pub struct GpuContext {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: Option<AdapterInfo>,
    /// What the adapter can do below WebGPU's baseline (GL drivers lack some).
    downlevel: Option<wgpu::DownlevelFlags>,
    lost: Option<Arc<AtomicBool>>,
    /// The pipelines built on this device, shared by every `GpuCollision` made on it.
    kernels: Arc<Mutex<super::KernelCache>>,
}

impl GpuContext {
    /// Opens a device on the best adapter there is: a discrete GPU before an integrated one,
    /// before a virtual one, before a software one (Mesa lavapipe/llvmpipe, WARP), which is
    /// accepted. wgpu's environment overrides are honoured: `WGPU_BACKEND` (e.g. `vulkan`, `gl`)
    /// limits the backends searched, and `WGPU_ADAPTER_NAME` picks the first adapter whose name
    /// contains it (case-insensitive). The device gets the adapter's own limits, not wgpu's
    /// defaults, and no optional feature but timestamp queries where the adapter has them (for
    /// [`GpuCollision::set_profiling`](crate::GpuCollision::set_profiling)).
    ///
    /// # Errors
    /// [`Error::NoAdapter`] when no adapter with compute shaders is found (or none matches
    /// `WGPU_ADAPTER_NAME`), or the device cannot be opened.
    pub fn new() -> Result<GpuContext, Error> {
        // Without WGPU_BACKEND, the native backends are searched first and GL only when they
        // offer nothing (probing GL wakes EGL, which is slow and noisy on headless machines).
        let searches = match wgpu::Backends::from_env() {
            Some(backends) => vec![backends],
            None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY],
        };
        let mut adapters: Vec<Adapter> = Vec::new();
        for backends in searches {
            let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
                backends,
                ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
            });
            adapters = pollster::block_on(instance.enumerate_adapters(backends))
                .into_iter()
                .filter(|a| {
                    a.get_downlevel_capabilities().flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
                })
                .collect();
            if !adapters.is_empty() {
                break;
            }
        }
        let names = || adapters.iter().map(|a| describe(&a.get_info())).collect::<Vec<_>>().join("; ");
        let wanted = std::env::var("WGPU_ADAPTER_NAME").ok().filter(|s| !s.is_empty());
        let chosen = match &wanted {
            Some(name) => {
                let lower = name.to_lowercase();
                adapters.iter().find(|a| a.get_info().name.to_lowercase().contains(&lower)).ok_or_else(
                    || Error::NoAdapter {
                        message: format!(
                            "WGPU_ADAPTER_NAME={name:?} matches none of the adapters found: [{}]",
                            names()
                        ),
                    },
                )?
            }
            None => adapters.iter().min_by_key(|a| rank(&a.get_info())).ok_or_else(|| Error::NoAdapter {
                message:
                    "no adapter with compute shaders was found (set WGPU_BACKEND to widen the search, or \
                          install a Vulkan driver such as Mesa's lavapipe: mesa-vulkan-drivers)"
                        .into(),
            })?,
        };
        let info = chosen.get_info();
        let (device, queue) = pollster::block_on(chosen.request_device(&wgpu::DeviceDescriptor {
            label: Some("voxcollide"),
            // Timestamp queries where the adapter has them, for GpuCollision::set_profiling.
            required_features: chosen.features() & wgpu::Features::TIMESTAMP_QUERY,
            required_limits: chosen.limits(),
            ..Default::default()
        }))
        .map_err(|e| Error::NoAdapter {
            message: format!("could not open a device on {}: {e}", describe(&info)),
        })?;
        let lost = Arc::new(AtomicBool::new(false));
        let flag = lost.clone();
        device.set_device_lost_callback(move |_, _| flag.store(true, Ordering::SeqCst));
        let downlevel = Some(chosen.get_downlevel_capabilities().flags);
        Ok(GpuContext {
            device,
            queue,
            adapter: Some(info),
            downlevel,
            lost: Some(lost),
            kernels: Arc::default(),
        })
    }

    /// Wraps an app's own device and queue (the app keeps its error and device-lost handlers).
    #[must_use]
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> GpuContext {
        GpuContext { device, queue, adapter: None, downlevel: None, lost: None, kernels: Arc::default() }
    }

    /// Wraps an app's own device and queue, opened on `adapter`, whose name, type and
    /// capabilities it then reports ([`adapter_info`](Self::adapter_info),
    /// [`downlevel_flags`](Self::downlevel_flags)); the app keeps its error and device-lost
    /// handlers, as with [`from_device`](Self::from_device).
    #[must_use]
    pub fn from_adapter(adapter: &Adapter, device: wgpu::Device, queue: wgpu::Queue) -> GpuContext {
        GpuContext {
            adapter: Some(adapter.get_info()),
            downlevel: Some(adapter.get_downlevel_capabilities().flags),
            ..GpuContext::from_device(device, queue)
        }
    }

    /// The device.
    #[must_use]
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue.
    #[must_use]
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The adapter [`new`](Self::new) chose; `None` for a context made with
    /// [`from_device`](Self::from_device).
    #[must_use]
    pub fn adapter_info(&self) -> Option<&AdapterInfo> {
        self.adapter.as_ref()
    }

    /// The adapter's downlevel flags (what it can do below WebGPU's baseline); `None` for a
    /// context made with [`from_device`](Self::from_device).
    #[must_use]
    pub fn downlevel_flags(&self) -> Option<wgpu::DownlevelFlags> {
        self.downlevel
    }

    /// The adapter in words, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)`.
    #[must_use]
    pub fn adapter_name(&self) -> String {
        self.adapter.as_ref().map_or_else(|| "app-provided device".to_string(), describe)
    }

    /// The kernels of `key` on this device: built by `build` the first time, shared after (a
    /// pipeline takes milliseconds to build; a collision on a warm context takes none).
    pub(super) fn kernels<K, E>(
        &self,
        key: K,
        build: impl FnOnce() -> Result<Arc<super::Kernels>, E>,
    ) -> Result<Arc<super::Kernels>, E>
    where
        K: Into<super::KernelKey>,
    {
        let key = key.into();
        // A poisoned lock only means another thread panicked while building: the cache holds
        // whole entries either way.
        let mut cache = self.kernels.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, k)) = cache.iter().find(|(k, _)| *k == key) {
            return Ok(k.clone());
        }
        let kernels = build()?;
        cache.push((key, kernels.clone()));
        Ok(kernels)
    }

    /// Whether the device was reported lost (only known for contexts made by [`new`](Self::new)).
    #[must_use]
    pub fn is_lost(&self) -> bool {
        self.lost.as_ref().is_some_and(|l| l.load(Ordering::SeqCst))
    }
}

fn describe(info: &AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

/// Lower is better: hardware before software, then the native backends before GL.
fn rank(info: &AdapterInfo) -> (u8, u8) {
    let kind = match info.device_type {
        DeviceType::DiscreteGpu => 0,
        DeviceType::IntegratedGpu => 1,
        DeviceType::VirtualGpu => 2,
        DeviceType::Other => 3,
        DeviceType::Cpu => 4,
    };
    let backend = match info.backend {
        Backend::Vulkan | Backend::Metal | Backend::Dx12 => 0,
        _ => 1,
    };
    (kind, backend)
}
