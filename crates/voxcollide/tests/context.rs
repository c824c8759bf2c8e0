//! `GpuContext::new` honours wgpu's environment overrides. One test in its own process, since it
//! changes the environment.

mod common;

use voxcollide::{Error, GpuContext, wgpu};

#[test]
fn adapter_choice_follows_wgpu_adapter_name_and_wgpu_backend() {
    let Some(ctx) = common::gpu() else { return };
    let info = ctx.adapter_info().expect("new() records its adapter").clone();
    assert!(ctx.adapter_name().contains(&info.name));
    // Limits are the adapter's own, not wgpu's defaults.
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapters = pollster::block_on(instance.enumerate_adapters(info.backend.into()));
    let adapter = adapters.iter().find(|a| a.get_info().name == info.name).expect("the same adapter again");
    assert_eq!(ctx.device().limits(), adapter.limits());

    // SAFETY: this test file runs this one test alone in its process; nothing reads the
    // environment concurrently.
    unsafe { std::env::set_var("WGPU_ADAPTER_NAME", "no-such-adapter-anywhere") };
    let err = GpuContext::new().unwrap_err();
    assert!(matches!(err, Error::NoAdapter { .. }), "{err:?}");
    assert!(
        err.to_string().contains("no-such-adapter-anywhere") && err.to_string().contains(&info.name),
        "{err}"
    );

    let part = info.name.split_whitespace().next().unwrap().to_uppercase();
    unsafe { std::env::set_var("WGPU_ADAPTER_NAME", &part) };
    assert_eq!(GpuContext::new().unwrap().adapter_info().unwrap().name, info.name, "case-insensitive match");

    unsafe { std::env::remove_var("WGPU_ADAPTER_NAME") };
    unsafe { std::env::set_var("WGPU_BACKEND", "noop") };
    assert!(matches!(GpuContext::new().unwrap_err(), Error::NoAdapter { .. }));
    unsafe { std::env::remove_var("WGPU_BACKEND") };
}
