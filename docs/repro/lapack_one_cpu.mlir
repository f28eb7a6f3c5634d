module @jit_flat attributes {mhlo.num_partitions = 1 : i32, mhlo.num_replicas = 1 : i32} {
  func.func public @main(%arg0: tensor<13xf64>) -> (tensor<10256xf64> {jax.result_info = "result"}) {
    %cst = stablehlo.constant dense<0x7FF0000000000000> : tensor<f64>
    %cst_0 = stablehlo.constant dense<0.000000e+00> : tensor<2048xf64>
    %cst_1 = stablehlo.constant dense<0.000000e+00> : tensor<8192xf64>
    %cst_2 = stablehlo.constant dense<0x7FF8000000000000> : tensor<f64>
    %c = stablehlo.constant dense<1024> : tensor<i64>
    %c_3 = stablehlo.constant dense<> : tensor<0xi32>
    %cst_4 = stablehlo.constant dense<1.000000e+00> : tensor<3xf64>
    %cst_5 = stablehlo.constant dense<5.000000e-01> : tensor<f64>
    %cst_6 = stablehlo.constant dense<0.000000e+00> : tensor<3xf64>
    %cst_7 = stablehlo.constant dense<0.000000e+00> : tensor<0xf64>
    %cst_8 = stablehlo.constant dense<0.000000e+00> : tensor<f64>
    %cst_9 = stablehlo.constant dense<0.000000e+00> : tensor<2xf64>
    %cst_10 = stablehlo.constant dense<0.000000e+00> : tensor<3x3xf64>
    %c_11 = stablehlo.constant dense<0> : tensor<3xi32>
    %c_12 = stablehlo.constant dense<0> : tensor<i64>
    %c_13 = stablehlo.constant dense<false> : tensor<i1>
    %cst_14 = stablehlo.constant dense<0.000000e+00> : tensor<1024xf64>
    %c_15 = stablehlo.constant dense<0> : tensor<1024xi64>
    %c_16 = stablehlo.constant dense<false> : tensor<1024xi1>
    %cst_17 = stablehlo.constant dense<0.000000e+00> : tensor<1024x3xf64>
    %cst_18 = stablehlo.constant dense<0.000000e+00> : tensor<1024x0xf64>
    %0:24 = stablehlo.while(%iterArg = %cst_14, %iterArg_19 = %c_16, %iterArg_20 = %c_3, %iterArg_21 = %cst_8, %iterArg_22 = %cst_4, %iterArg_23 = %cst_5, %iterArg_24 = %cst_4, %iterArg_25 = %cst_5, %iterArg_26 = %c_12, %iterArg_27 = %cst_6, %iterArg_28 = %cst_6, %iterArg_29 = %cst_6, %iterArg_30 = %cst_7, %iterArg_31 = %cst_10, %iterArg_32 = %c_11, %iterArg_33 = %cst_10, %iterArg_34 = %c_13, %iterArg_35 = %c_13, %iterArg_36 = %cst_17, %iterArg_37 = %cst_17, %iterArg_38 = %cst_18, %iterArg_39 = %c_15, %iterArg_40 = %cst_14, %iterArg_41 = %c_15) : tensor<1024xf64>, tensor<1024xi1>, tensor<0xi32>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<i64>, tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>, tensor<i1>, tensor<1024x3xf64>, tensor<1024x3xf64>, tensor<1024x0xf64>, tensor<1024xi64>, tensor<1024xf64>, tensor<1024xi64>
    cond {
      %22 = stablehlo.compare LT, %iterArg_26, %c, SIGNED : (tensor<i64>, tensor<i64>) -> tensor<i1>
      stablehlo.return %22 : tensor<i1>
    } do {
      %22:15 = func.call @closed_call(%iterArg_20, %iterArg_21, %iterArg_22, %iterArg_23, %iterArg_24, %iterArg_25, %iterArg_27, %iterArg_28, %iterArg_29, %iterArg_30, %iterArg_31, %iterArg_32, %iterArg_33, %iterArg_34, %iterArg_35, %cst_8, %c_13) : (tensor<0xi32>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>, tensor<i1>, tensor<f64>, tensor<i1>) -> (tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>, tensor<i1>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<i64>, tensor<f64>, tensor<i64>)
      %23 = func.call @dynamic_update_index_in_dim_11(%iterArg_40, %22#13, %iterArg_26) : (tensor<1024xf64>, tensor<f64>, tensor<i64>) -> tensor<1024xf64>
      stablehlo.return %iterArg, %iterArg_19, %iterArg_20, %iterArg_21, %iterArg_22, %iterArg_23, %iterArg_24, %iterArg_25, %c_12, %22#0, %22#1, %22#2, %22#3, %22#4, %22#5, %22#6, %22#7, %22#8, %cst_17, %cst_17, %cst_18, %c_15, %23, %c_15 : tensor<1024xf64>, tensor<1024xi1>, tensor<0xi32>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<i64>, tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>, tensor<i1>, tensor<1024x3xf64>, tensor<1024x3xf64>, tensor<1024x0xf64>, tensor<1024xi64>, tensor<1024xf64>, tensor<1024xi64>
    }
    %1 = call @_where_12(%c_16, %0#23, %c_12) : (tensor<1024xi1>, tensor<1024xi64>, tensor<i64>) -> tensor<1024xi64>
    %2 = call @argmin(%c_16) : (tensor<1024xi1>) -> tensor<i64>
    %3 = stablehlo.compare EQ, %c_12, %c_12, SIGNED : (tensor<i64>, tensor<i64>) -> tensor<i1>
    %4 = stablehlo.not %c_13 : tensor<i1>
    %5 = stablehlo.compare NE, %3, %c_13, UNSIGNED : (tensor<i1>, tensor<i1>) -> tensor<i1>
    %6 = stablehlo.convert %5 : tensor<i1>
    %7 = stablehlo.and %6, %4 : tensor<i1>
    %8 = stablehlo.select %c_13, %c_12, %2 : tensor<i1>, tensor<i64>
    %9 = stablehlo.dynamic_slice %0#22, %8, sizes = [1] : (tensor<1024xf64>, tensor<i64>) -> tensor<1xf64>
    %10 = stablehlo.reshape %9 : (tensor<1xf64>) -> tensor<f64>
    %11 = call @_where_5(%7, %c_12, %c_12) : (tensor<i1>, tensor<i64>, tensor<i64>) -> tensor<i64>
    %12 = call @_where_5(%7, %c_12, %c_12) : (tensor<i1>, tensor<i64>, tensor<i64>) -> tensor<i64>
    %13 = call @_where_13(%7, %10, %cst_2) : (tensor<i1>, tensor<f64>, tensor<f64>) -> tensor<f64>
    %14 = call @_where_14(%7, %cst_6, %cst_6) : (tensor<i1>, tensor<3xf64>, tensor<3xf64>) -> tensor<3xf64>
    %15 = call @argmin(%c_16) : (tensor<1024xi1>) -> tensor<i64>
    %16 = call @_where_15(%c_13, %c, %15) : (tensor<i1>, tensor<i64>, tensor<i64>) -> tensor<i64>
    %17 = stablehlo.broadcast_in_dim %13, dims = [] : (tensor<f64>) -> tensor<1xf64>
    %18 = stablehlo.concatenate %0#9, %0#10, %0#11, %0#12, %17, %14, dim = 0 : (tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<1xf64>, tensor<3xf64>) -> tensor<13xf64>
    %19 = stablehlo.concatenate %cst_1, %cst_0, %18, %cst_9, dim = 0 : (tensor<8192xf64>, tensor<2048xf64>, tensor<13xf64>, tensor<2xf64>) -> tensor<10255xf64>
    %20 = call @_where_16(%c_13, %cst_8, %cst) : (tensor<i1>, tensor<f64>, tensor<f64>) -> tensor<f64>
    %21 = call @append(%19, %20) : (tensor<10255xf64>, tensor<f64>) -> tensor<10256xf64>
    return %21 : tensor<10256xf64>
  }
  func.func private @closed_call(%arg0: tensor<0xi32>, %arg1: tensor<f64>, %arg2: tensor<3xf64>, %arg3: tensor<f64>, %arg4: tensor<3xf64>, %arg5: tensor<f64>, %arg6: tensor<3xf64>, %arg7: tensor<3xf64>, %arg8: tensor<3xf64>, %arg9: tensor<0xf64>, %arg10: tensor<3x3xf64>, %arg11: tensor<3xi32>, %arg12: tensor<3x3xf64>, %arg13: tensor<i1>, %arg14: tensor<i1>, %arg15: tensor<f64>, %arg16: tensor<i1>) -> (tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>, tensor<i1>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<i64>, tensor<f64>, tensor<i64>) {
    %cst = stablehlo.constant dense<0x7FF8000000000000> : tensor<f64>
    %c = stablehlo.constant dense<true> : tensor<i1>
    %cst_0 = stablehlo.constant dense<0.000000e+00> : tensor<3x3xf64>
    %cst_1 = stablehlo.constant dense<0.000000e+00> : tensor<2xf64>
    %cst_2 = stablehlo.constant dense<0.000000e+00> : tensor<1xf64>
    %cst_3 = stablehlo.constant dense<0x7FF0000000000000> : tensor<f64>
    %c_4 = stablehlo.constant dense<0> : tensor<i64>
    %c_5 = stablehlo.constant dense<-1> : tensor<i64>
    %cst_6 = stablehlo.constant dense<0xFFF0000000000000> : tensor<f64>
    %cst_7 = stablehlo.constant dense<0.000000e+00> : tensor<0xf64>
    %cst_8 = stablehlo.constant dense<0.000000e+00> : tensor<f64>
    %cst_9 = stablehlo.constant dense<0.000000e+00> : tensor<3xf64>
    %c_10 = stablehlo.constant dense<false> : tensor<i1>
    %0 = stablehlo.convert %c_10 : (tensor<i1>) -> tensor<i32>
    %1:10 = "stablehlo.case"(%0) ({
      %8 = "stablehlo.scatter"(%cst_9, %arg0, %cst_9) <{indices_are_sorted = true, scatter_dimension_numbers = #stablehlo.scatter<update_window_dims = [0]>, unique_indices = true}> ({
      ^bb0(%arg17: tensor<f64>, %arg18: tensor<f64>):
        stablehlo.return %arg18 : tensor<f64>
      }) : (tensor<3xf64>, tensor<0xi32>, tensor<3xf64>) -> tensor<3xf64>
      %9:20 = stablehlo.while(%iterArg = %arg6, %iterArg_11 = %arg1, %iterArg_12 = %arg15, %iterArg_13 = %arg2, %iterArg_14 = %arg3, %iterArg_15 = %arg4, %iterArg_16 = %arg5, %iterArg_17 = %arg7, %iterArg_18 = %cst_9, %iterArg_19 = %8, %iterArg_20 = %cst_8, %iterArg_21 = %cst_9, %iterArg_22 = %c_5, %iterArg_23 = %c_4, %iterArg_24 = %cst_3, %iterArg_25 = %cst_3, %iterArg_26 = %arg10, %iterArg_27 = %arg11, %iterArg_28 = %arg12, %iterArg_29 = %arg13) : tensor<3xf64>, tensor<f64>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<i64>, tensor<i64>, tensor<f64>, tensor<f64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>
      cond {
        stablehlo.return %c_10 : tensor<i1>
      } do {
        %10 = stablehlo.add %iterArg, %iterArg_21 : tensor<3xf64>
        %11 = stablehlo.multiply %cst_9, %10 : tensor<3xf64>
        %12 = stablehlo.slice %11 [0:2] : (tensor<3xf64>) -> tensor<2xf64>
        %13 = stablehlo.subtract %cst_1, %12 : tensor<2xf64>
        %14 = stablehlo.concatenate %cst_2, %13, dim = 0 : (tensor<1xf64>, tensor<2xf64>) -> tensor<3xf64>
        %15 = stablehlo.multiply %cst_9, %14 : tensor<3xf64>
        %16 = stablehlo.multiply %cst_9, %15 : tensor<3xf64>
        %17 = stablehlo.slice %16 [0:1] : (tensor<3xf64>) -> tensor<1xf64>
        %18 = stablehlo.pad %17, %cst_8, low = [0], high = [2], interior = [0] : (tensor<1xf64>, tensor<f64>) -> tensor<3xf64>
        %19 = stablehlo.add %cst_9, %18 : tensor<3xf64>
        %20 = stablehlo.multiply %cst_9, %19 : tensor<3xf64>
        %21 = stablehlo.add %cst_9, %20 : tensor<3xf64>
        %22 = stablehlo.negate %21 : tensor<3xf64>
        %23 = stablehlo.add %22, %cst_9 : tensor<3xf64>
        %24 = stablehlo.subtract %23, %iterArg_17 : tensor<3xf64>
        %25 = stablehlo.concatenate %24, %cst_7, dim = 0 : (tensor<3xf64>, tensor<0xf64>) -> tensor<3xf64>
        %26:2 = func.call @lu_factor(%cst_0) : (tensor<3x3xf64>) -> (tensor<3x3xf64>, tensor<3xi32>)
        %27 = func.call @lu_solve(%26#0, %26#1, %cst_9) : (tensor<3x3xf64>, tensor<3xi32>, tensor<3xf64>) -> tensor<3xf64>
        %28 = stablehlo.is_finite %25 : (tensor<3xf64>) -> tensor<3xi1>
        %29 = stablehlo.reduce(%28 init: %c) applies stablehlo.and across dimensions = [0] : (tensor<3xi1>, tensor<i1>) -> tensor<i1>
        %30 = stablehlo.broadcast_in_dim %29, dims = [] : (tensor<i1>) -> tensor<1xi1>
        %31 = stablehlo.reduce(%30 init: %c) applies stablehlo.and across dimensions = [0] : (tensor<1xi1>, tensor<i1>) -> tensor<i1>
        %32 = stablehlo.is_finite %27 : (tensor<3xf64>) -> tensor<3xi1>
        %33 = stablehlo.reduce(%32 init: %c) applies stablehlo.and across dimensions = [0] : (tensor<3xi1>, tensor<i1>) -> tensor<i1>
        %34 = stablehlo.broadcast_in_dim %33, dims = [] : (tensor<i1>) -> tensor<1xi1>
        %35 = stablehlo.reduce(%34 init: %c) applies stablehlo.and across dimensions = [0] : (tensor<1xi1>, tensor<i1>) -> tensor<i1>
        %36 = stablehlo.abs %25 : tensor<3xf64>
        %37 = stablehlo.reduce(%36 init: %cst_6) applies stablehlo.maximum across dimensions = [0] : (tensor<3xf64>, tensor<f64>) -> tensor<f64>
        %38 = stablehlo.maximum %cst_8, %37 : tensor<f64>
        %39 = stablehlo.broadcast_in_dim %38, dims = [] : (tensor<f64>) -> tensor<1xf64>
        %40 = stablehlo.reduce(%39 init: %cst_6) applies stablehlo.maximum across dimensions = [0] : (tensor<1xf64>, tensor<f64>) -> tensor<f64>
        %41 = stablehlo.and %35, %31 : tensor<i1>
        %42 = stablehlo.not %c_10 : tensor<i1>
        %43 = stablehlo.and %41, %42 : tensor<i1>
        %44 = func.call @_where_2(%43, %cst_9, %iterArg_21) : (tensor<i1>, tensor<3xf64>, tensor<3xf64>) -> tensor<3xf64>
        stablehlo.return %iterArg, %iterArg_11, %iterArg_12, %iterArg_13, %iterArg_14, %iterArg_15, %iterArg_16, %iterArg_17, %iterArg_18, %iterArg_19, %iterArg_20, %44, %c_4, %c_4, %cst_8, %40, %26#0, %26#1, %cst_0, %c_10 : tensor<3xf64>, tensor<f64>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<f64>, tensor<3xf64>, tensor<i64>, tensor<i64>, tensor<f64>, tensor<f64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>
      }
      stablehlo.return %9#11, %cst_9, %cst_7, %9#13, %9#15, %c_4, %9#16, %9#17, %9#18, %c_10 : tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<i64>, tensor<f64>, tensor<i64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>
    }, {
      %8 = stablehlo.concatenate %arg6, %arg9, dim = 0 : (tensor<3xf64>, tensor<0xf64>) -> tensor<3xf64>
      %9 = stablehlo.slice %8 [3:3] : (tensor<3xf64>) -> tensor<0xf64>
      stablehlo.return %arg6, %arg7, %9, %c_4, %cst, %c_5, %arg10, %arg11, %arg12, %arg13 : tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<i64>, tensor<f64>, tensor<i64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>
    }) : (tensor<i32>) -> (tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<i64>, tensor<f64>, tensor<i64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>)
    %2 = call @_where_6(%c_10, %1#0, %arg6) : (tensor<i1>, tensor<3xf64>, tensor<3xf64>) -> tensor<3xf64>
    %3 = call @_where_6(%c_10, %1#1, %arg7) : (tensor<i1>, tensor<3xf64>, tensor<3xf64>) -> tensor<3xf64>
    %4 = call @_where_6(%c_10, %arg6, %arg8) : (tensor<i1>, tensor<3xf64>, tensor<3xf64>) -> tensor<3xf64>
    %5 = call @_where_7(%1#2) : (tensor<0xf64>) -> tensor<0xf64>
    %6 = call @_where_8(%arg16, %c_10, %arg14) : (tensor<i1>, tensor<i1>, tensor<i1>) -> tensor<i1>
    %7 = call @_where_5(%arg16, %1#5, %c_4) : (tensor<i1>, tensor<i64>, tensor<i64>) -> tensor<i64>
    return %2, %3, %4, %5, %1#6, %1#7, %1#8, %1#9, %6, %1#0, %1#1, %1#2, %1#3, %1#4, %7 : tensor<3xf64>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<3x3xf64>, tensor<3xi32>, tensor<3x3xf64>, tensor<i1>, tensor<i1>, tensor<3xf64>, tensor<3xf64>, tensor<0xf64>, tensor<i64>, tensor<f64>, tensor<i64>
  }
  func.func private @lu_factor(%arg0: tensor<3x3xf64>) -> (tensor<3x3xf64>, tensor<3xi32>) {
    %cst = stablehlo.constant dense<0.000000e+00> : tensor<3x3xf64>
    %c = stablehlo.constant dense<0> : tensor<3xi32>
    return %cst, %c : tensor<3x3xf64>, tensor<3xi32>
  }
  func.func private @closed_call_1(%arg0: tensor<3xi32>, %arg1: tensor<i64>, %arg2: tensor<3xi32>) -> (tensor<i64>, tensor<3xi32>) {
    %c = stablehlo.constant dense<0> : tensor<i64>
    %c_0 = stablehlo.constant dense<0> : tensor<3xi32>
    return %c, %c_0 : tensor<i64>, tensor<3xi32>
  }
  func.func private @lu_solve(%arg0: tensor<3x3xf64>, %arg1: tensor<3xi32>, %arg2: tensor<3xf64>) -> tensor<3xf64> {
    %c = stablehlo.constant dense<false> : tensor<i1>
    %c_0 = stablehlo.constant dense<0> : tensor<3xi32>
    %c_1 = stablehlo.constant dense<0> : tensor<i64>
    %0:4 = stablehlo.while(%iterArg = %arg1, %iterArg_2 = %c_1, %iterArg_3 = %c_1, %iterArg_4 = %c_0) : tensor<3xi32>, tensor<i64>, tensor<i64>, tensor<3xi32>
    cond {
      stablehlo.return %c : tensor<i1>
    } do {
      %2:2 = func.call @closed_call_1(%iterArg, %iterArg_3, %iterArg_4) : (tensor<3xi32>, tensor<i64>, tensor<3xi32>) -> (tensor<i64>, tensor<3xi32>)
      stablehlo.return %iterArg, %c_1, %2#0, %2#1 : tensor<3xi32>, tensor<i64>, tensor<i64>, tensor<3xi32>
    }
    %1 = call @_lu_solve(%arg0, %0#3, %arg2) : (tensor<3x3xf64>, tensor<3xi32>, tensor<3xf64>) -> tensor<3xf64>
    return %1 : tensor<3xf64>
  }
  func.func private @_lu_solve(%arg0: tensor<3x3xf64>, %arg1: tensor<3xi32>, %arg2: tensor<3xf64>) -> tensor<3xf64> {
    %cst = stablehlo.constant dense<0.000000e+00> : tensor<3x1xf64>
    %0 = stablehlo.custom_call @lapack_dtrsm_ffi(%arg0, %cst) {backend_config = "", mhlo.backend_config = {diag = 78 : ui8, side = 76 : ui8, trans_x = 78 : ui8, uplo = 85 : ui8}, mhlo.frontend_attributes = {num_batch_dims = "0"}, operand_layouts = [dense<[0, 1]> : tensor<2xindex>, dense<[0, 1]> : tensor<2xindex>], output_operand_aliases = [#stablehlo.output_operand_alias<output_tuple_indices = [], operand_index = 1, operand_tuple_indices = []>], result_layouts = [dense<[0, 1]> : tensor<2xindex>], sdy.sharding_rule = #sdy.op_sharding_rule<([i, j], [k, l])->([m, n]) {i=3, j=3, k=3, l=1, m=3, n=1}, custom>} : (tensor<3x3xf64>, tensor<3x1xf64>) -> tensor<3x1xf64>
    %1 = stablehlo.reshape %0 : (tensor<3x1xf64>) -> tensor<3xf64>
    return %1 : tensor<3xf64>
  }
  func.func private @_where_2(%arg0: tensor<i1>, %arg1: tensor<3xf64>, %arg2: tensor<3xf64>) -> tensor<3xf64> {
    %0 = stablehlo.select %arg0, %arg1, %arg2 : tensor<i1>, tensor<3xf64>
    return %0 : tensor<3xf64>
  }
  func.func private @_where_5(%arg0: tensor<i1>, %arg1: tensor<i64>, %arg2: tensor<i64>) -> tensor<i64> {
    %c = stablehlo.constant dense<0> : tensor<i64>
    return %c : tensor<i64>
  }
  func.func private @_where_6(%arg0: tensor<i1>, %arg1: tensor<3xf64>, %arg2: tensor<3xf64>) -> tensor<3xf64> {
    %cst = stablehlo.constant dense<0.000000e+00> : tensor<3xf64>
    return %cst : tensor<3xf64>
  }
  func.func private @_where_7(%arg0: tensor<0xf64>) -> tensor<0xf64> {
    %cst = stablehlo.constant dense<0.000000e+00> : tensor<0xf64>
    return %cst : tensor<0xf64>
  }
  func.func private @_where_8(%arg0: tensor<i1>, %arg1: tensor<i1>, %arg2: tensor<i1>) -> tensor<i1> {
    %c = stablehlo.constant dense<false> : tensor<i1>
    return %c : tensor<i1>
  }
  func.func private @dynamic_update_index_in_dim_11(%arg0: tensor<1024xf64>, %arg1: tensor<f64>, %arg2: tensor<i64>) -> tensor<1024xf64> {
    %0 = stablehlo.broadcast_in_dim %arg1, dims = [] : (tensor<f64>) -> tensor<1xf64>
    %1 = stablehlo.dynamic_update_slice %arg0, %0, %arg2 : (tensor<1024xf64>, tensor<1xf64>, tensor<i64>) -> tensor<1024xf64>
    return %1 : tensor<1024xf64>
  }
  func.func private @_where_12(%arg0: tensor<1024xi1>, %arg1: tensor<1024xi64>, %arg2: tensor<i64>) -> tensor<1024xi64> {
    %c = stablehlo.constant dense<0> : tensor<1024xi64>
    %0 = stablehlo.select %arg0, %arg1, %c : tensor<1024xi1>, tensor<1024xi64>
    return %0 : tensor<1024xi64>
  }
  func.func private @argmin(%arg0: tensor<1024xi1>) -> tensor<i64> {
    %c = stablehlo.constant dense<0> : tensor<i64>
    return %c : tensor<i64>
  }
  func.func private @_where_13(%arg0: tensor<i1>, %arg1: tensor<f64>, %arg2: tensor<f64>) -> tensor<f64> {
    %0 = stablehlo.select %arg0, %arg1, %arg2 : tensor<i1>, tensor<f64>
    return %0 : tensor<f64>
  }
  func.func private @_where_14(%arg0: tensor<i1>, %arg1: tensor<3xf64>, %arg2: tensor<3xf64>) -> tensor<3xf64> {
    %cst = stablehlo.constant dense<0.000000e+00> : tensor<3xf64>
    return %cst : tensor<3xf64>
  }
  func.func private @_where_15(%arg0: tensor<i1>, %arg1: tensor<i64>, %arg2: tensor<i64>) -> tensor<i64> {
    %c = stablehlo.constant dense<0> : tensor<i64>
    return %c : tensor<i64>
  }
  func.func private @_where_16(%arg0: tensor<i1>, %arg1: tensor<f64>, %arg2: tensor<f64>) -> tensor<f64> {
    %cst = stablehlo.constant dense<0.000000e+00> : tensor<f64>
    return %cst : tensor<f64>
  }
  func.func private @append(%arg0: tensor<10255xf64>, %arg1: tensor<f64>) -> tensor<10256xf64> {
    %cst = stablehlo.constant dense<0.000000e+00> : tensor<1xf64>
    %0 = stablehlo.concatenate %arg0, %cst, dim = 0 : (tensor<10255xf64>, tensor<1xf64>) -> tensor<10256xf64>
    return %0 : tensor<10256xf64>
  }
}
